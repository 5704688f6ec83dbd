// Small scenes for the derivative tests: fast to render, one parameter of each kind.
#pragma once

#include "test_util.h"

namespace invr::test {

// A textured diffuse wall and a rough metal plate lit by an area light, a point light and a dim
// constant environment. 32x24 pixels.
inline constexpr const char* kDiffScene = R"({
  "materials": [
    {"name": "wall", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 4,
      "color_a": {"r": 0.7, "g": 0.6, "b": 0.5}, "color_b": {"r": 0.3, "g": 0.35, "b": 0.4}}}}},
    {"name": "metal", "rough_conductor": {"roughness": {"value": 0.3}}},
    {"name": "lamp", "diffuse": {"albedo": {"value": 0.5}}}
  ],
  "shapes": [
    {"name": "wall", "material": "wall", "quad": {}, "transform": {"scale": {"x": 2, "y": 1.5, "z": 1}}},
    {"name": "plate", "material": "metal", "quad": {},
     "transform": {"scale": {"x": 0.6, "y": 0.6, "z": 1}, "rotate_xyz_degrees": {"x": -60}, "translate": {"x": 0.5, "y": -0.6, "z": 0.6}}},
    {"name": "lamp", "material": "lamp", "quad": {},
     "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"x": 70}, "translate": {"x": -0.8, "y": 1.2, "z": 1.2}}}
  ],
  "lights": [
    {"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 8, "g": 8, "b": 7}}},
    {"name": "bulb", "point": {"position": {"x": 1.2, "y": 0.8, "z": 1.8}, "intensity": {"r": 1.5, "g": 1.4, "b": 1.2}}},
    {"name": "sky", "constant_environment": {"radiance": {"r": 0.05, "g": 0.05, "b": 0.06}}}
  ],
  "views": [{"eye": {"z": 3.5}, "target": {}, "fov_y_degrees": 45}],
  "film": {"width": 32, "height": 24}
})";

// Seen through a glossy mirror only: a textured wall and a glossy sphere behind the camera, lit
// by an area light (also behind the camera) and a dim environment. Multi-bounce derivatives:
// the wall's albedo and the sphere's roughness reach the image only after a reflection. 40x30.
inline constexpr const char* kReflectionScene = R"({
  "materials": [
    {"name": "mirror", "rough_conductor": {"roughness": {"value": 0.25}}},
    {"name": "wall", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 4,
      "color_a": {"r": 0.75, "g": 0.6, "b": 0.45}, "color_b": {"r": 0.25, "g": 0.35, "b": 0.5}}}}},
    {"name": "gloss", "rough_conductor": {"roughness": {"value": 0.3}}},
    {"name": "lamp", "diffuse": {"albedo": {"value": 0.5}}}
  ],
  "shapes": [
    {"name": "mirror", "material": "mirror", "quad": {}, "transform": {"scale": {"x": 1.6, "y": 1.2, "z": 1}}},
    {"name": "wall", "material": "wall", "quad": {},
     "transform": {"scale": {"x": 2.5, "y": 2, "z": 1}, "rotate_xyz_degrees": {"y": 180}, "translate": {"z": 6}}},
    {"name": "ball", "material": "gloss", "sphere": {},
     "transform": {"scale": {"x": 0.8, "y": 0.8, "z": 0.8}, "translate": {"x": 0.6, "y": -0.4, "z": 4.6}}},
    {"name": "lamp", "material": "lamp", "quad": {},
     "transform": {"scale": {"x": 0.4, "y": 0.4, "z": 1}, "rotate_xyz_degrees": {"x": -20}, "translate": {"y": 1.7, "z": 3.6}}}
  ],
  "lights": [
    {"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 20, "g": 20, "b": 17}}},
    {"name": "sky", "constant_environment": {"radiance": {"r": 0.05, "g": 0.05, "b": 0.06}}}
  ],
  "views": [{"eye": {"z": 3.5}, "target": {}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 30}
})";

// A caustic: a lamp above a glass sphere that focuses it onto a textured floor, in a spot about
// 8x5 pixels: a stage-1 grid with no cell on the spot never sees it, so pixel sampling must stay
// unbiased through its defensive mixture. 32x24; needs paths of 4+ vertices.
inline constexpr const char* kCausticScene = R"({
  "materials": [
    {"name": "floor", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 4,
      "color_a": {"r": 0.8, "g": 0.75, "b": 0.7}, "color_b": {"r": 0.4, "g": 0.45, "b": 0.5}}}}},
    {"name": "glass", "dielectric": {"ior": 1.5}},
    {"name": "lamp", "diffuse": {"albedo": {"value": 0.5}}}
  ],
  "shapes": [
    {"name": "floor", "material": "floor", "quad": {},
     "transform": {"scale": {"x": 2, "y": 2, "z": 1}, "rotate_xyz_degrees": {"x": -90}}},
    {"name": "ball", "material": "glass", "sphere": {},
     "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "translate": {"y": 0.8}}},
    {"name": "lamp", "material": "lamp", "quad": {},
     "transform": {"scale": {"x": 1.0, "y": 1.0, "z": 1}, "rotate_xyz_degrees": {"x": 90}, "translate": {"y": 2.5}}}
  ],
  "lights": [
    {"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 12, "g": 11.5, "b": 11}}},
    {"name": "sky", "constant_environment": {"radiance": {"r": 0.05, "g": 0.05, "b": 0.06}}}
  ],
  "views": [{"eye": {"y": 2.2, "z": 2.6}, "target": {"y": 0.2}, "fov_y_degrees": 45}],
  "film": {"width": 32, "height": 24}
})";

}  // namespace invr::test
