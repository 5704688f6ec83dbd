// What a scene lets a job optimise (Mitsuba's mi.traverse for invr): every parameter name the
// registry accepts for this scene, with its size, shape, bounds, default learning rate and the
// Mitsuba 3 names that mean the same value. `invr params` and the DescribeScene RPC list it.
#pragma once

#include <string>
#include <vector>

#include "core/scene/scene.h"

namespace invr {

struct ParameterInfo {
  std::string name;                  // materials/red/albedo
  std::string kind;                  // albedo, roughness, light_intensity, translation, vertices, ...
  uint32_t size = 0;                 // values
  int width = 0, height = 0;         // textures and pixel maps; 0 for constants
  int channels = 0;                  // values per texel or element
  float lower = 0, upper = 0;        // default bounds
  float learningRate = 0;            // default learning rate
  std::vector<std::string> aliases;  // Mitsuba names accepted for it (red.reflectance.value)
};

// Built by asking the parameter registry about every name the scene could have, so the list is
// exactly what a job may name (a scene with one light has no light_logits, ...).
std::vector<ParameterInfo> optimisableParameters(const Scene& scene);

}  // namespace invr
