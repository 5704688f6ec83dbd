#include "core/scene/zoo.h"

#include <array>
#include <cmath>
#include <functional>

#include "core/error.h"
#include "core/io/suggest.h"

namespace invr {

namespace v1 = invr::v1;

namespace {

// Small builders so each scene reads like a description.
struct SceneMaker {
  v1::Scene s;

  static void set(v1::Vec3* v, double x, double y, double z) { v->set_x(x); v->set_y(y); v->set_z(z); }
  static void set(v1::Rgb* c, double r, double g, double b) { c->set_r(r); c->set_g(g); c->set_b(b); }

  v1::Material* diffuse(const std::string& name, double r, double g, double b) {
    auto* m = s.add_materials();
    m->set_name(name);
    set(m->mutable_diffuse()->mutable_albedo()->mutable_constant(), r, g, b);
    return m;
  }
  v1::Material* diffuseTexture(const std::string& name, const std::string& pattern, int res, uint64_t seed,
                               double ar, double ag, double ab, double br, double bg, double bb) {
    auto* m = s.add_materials();
    m->set_name(name);
    auto* p = m->mutable_diffuse()->mutable_albedo()->mutable_procedural();
    p->set_pattern(pattern);
    p->set_width(res);
    p->set_seed(seed);
    set(p->mutable_color_a(), ar, ag, ab);
    set(p->mutable_color_b(), br, bg, bb);
    return m;
  }
  v1::Shape* shape(const std::string& name, const std::string& material) {
    auto* sh = s.add_shapes();
    sh->set_name(name);
    sh->set_material(material);
    return sh;
  }
  // A unit primitive placed with scale, Euler rotation (degrees) and translation.
  static void place(v1::Shape* sh, std::array<double, 3> scale, std::array<double, 3> rot, std::array<double, 3> tr) {
    auto* t = sh->mutable_transform();
    set(t->mutable_scale(), scale[0], scale[1], scale[2]);
    set(t->mutable_rotate_xyz_degrees(), rot[0], rot[1], rot[2]);
    set(t->mutable_translate(), tr[0], tr[1], tr[2]);
  }
  v1::Shape* quad(const std::string& name, const std::string& material, std::array<double, 3> scale,
                  std::array<double, 3> rot, std::array<double, 3> tr) {
    auto* sh = shape(name, material);
    sh->mutable_quad();
    place(sh, scale, rot, tr);
    return sh;
  }
  void areaLight(const std::string& name, const std::string& shapeName, double r, double g, double b) {
    auto* l = s.add_lights();
    l->set_name(name);
    l->mutable_area()->set_shape(shapeName);
    set(l->mutable_area()->mutable_radiance(), r, g, b);
  }
  void spot(const std::string& name, std::array<double, 3> pos, std::array<double, 3> target, double intensity,
            double outer, double inner) {
    auto* l = s.add_lights();
    l->set_name(name);
    auto* sp = l->mutable_spot();
    set(sp->mutable_position(), pos[0], pos[1], pos[2]);
    set(sp->mutable_target(), target[0], target[1], target[2]);
    set(sp->mutable_intensity(), intensity, intensity * 0.95, intensity * 0.85);
    sp->set_cone_outer_degrees(outer);
    sp->set_cone_inner_degrees(inner);
  }
  void point(const std::string& name, std::array<double, 3> pos, double intensity) {
    auto* l = s.add_lights();
    l->set_name(name);
    set(l->mutable_point()->mutable_position(), pos[0], pos[1], pos[2]);
    set(l->mutable_point()->mutable_intensity(), intensity, intensity, intensity);
  }
  void view(const std::string& name, std::array<double, 3> eye, std::array<double, 3> target, double fov) {
    auto* c = s.add_views();
    c->set_name(name);
    set(c->mutable_eye(), eye[0], eye[1], eye[2]);
    set(c->mutable_target(), target[0], target[1], target[2]);
    set(c->mutable_up(), 0, 1, 0);
    c->set_fov_y_degrees(fov);
  }
  void film(int w, int h) { s.mutable_film()->set_width(w); s.mutable_film()->set_height(h); }
  // A room x in [-2, 2], y in [0, 2.5], z in [-2, 2] without its wall x = 2 (which each scene
  // builds around its own opening).
  void roomWithoutRightWall(const std::string& floorMaterial, const std::string& wallMaterial);
};


// Quad orientations (the unit quad faces +z).
constexpr std::array<double, 3> kFaceUp{-90, 0, 0}, kFaceDown{90, 0, 0}, kFacePosZ{0, 0, 0}, kFaceNegZ{0, 180, 0},
    kFacePosX{0, 90, 0}, kFaceNegX{0, -90, 0};

void SceneMaker::roomWithoutRightWall(const std::string& floorMaterial, const std::string& wallMaterial) {
  quad("floor", floorMaterial, {2, 2, 1}, kFaceUp, {0, 0, 0});
  quad("ceiling", wallMaterial, {2, 2, 1}, kFaceDown, {0, 2.5, 0});
  quad("back", wallMaterial, {2, 1.25, 1}, kFacePosZ, {0, 1.25, -2});
  quad("front", wallMaterial, {2, 1.25, 1}, kFaceNegZ, {0, 1.25, 2});
  quad("left", wallMaterial, {2, 1.25, 1}, kFacePosX, {-2, 1.25, 0});
}

v1::Scene cornell() {
  SceneMaker m;
  m.s.set_name("cornell");
  m.diffuse("white", 0.73, 0.73, 0.73);
  m.diffuse("red", 0.63, 0.065, 0.05);
  m.diffuse("green", 0.14, 0.45, 0.091);
  m.diffuse("light", 0.78, 0.78, 0.78);
  m.quad("floor", "white", {1, 1, 1}, kFaceUp, {0, 0, 0});
  m.quad("ceiling", "white", {1, 1, 1}, kFaceDown, {0, 2, 0});
  m.quad("back", "white", {1, 1, 1}, kFacePosZ, {0, 1, -1});
  m.quad("left", "red", {1, 1, 1}, kFacePosX, {-1, 1, 0});
  m.quad("right", "green", {1, 1, 1}, kFaceNegX, {1, 1, 0});
  m.quad("light", "light", {0.25, 0.25, 1}, kFaceDown, {0, 1.985, 0});
  auto* tall = m.shape("tall_box", "white");
  tall->mutable_box();
  SceneMaker::place(tall, {0.3, 0.6, 0.3}, {0, 20, 0}, {-0.33, 0.6, -0.3});
  auto* small = m.shape("short_box", "white");
  small->mutable_box();
  SceneMaker::place(small, {0.3, 0.3, 0.3}, {0, -18, 0}, {0.33, 0.3, 0.32});
  m.areaLight("ceiling_light", "light", 12.0, 8.6, 2.9);
  m.view("front", {0, 1, 3.9}, {0, 1, 0}, 38);
  m.film(256, 256);
  return m.s;
}

v1::Scene oxalis() {
  SceneMaker m;
  m.s.set_name("oxalis");
  m.diffuse("wall", 0.6, 0.58, 0.55);
  m.diffuse("floor", 0.35, 0.3, 0.25);
  m.diffuseTexture("painting", "painting", 64, 11, 0.15, 0.4, 0.15, 0.75, 0.65, 0.45);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  m.quad("wall", "wall", {3, 2, 1}, kFacePosZ, {0, 2, -0.01});
  m.quad("painting", "painting", {0.6, 0.45, 1}, kFacePosZ, {0, 1.3, 0});
  // Two bright, narrow spotlights pick out parts of the painting; a dim fill lights the rest.
  // Lights are selected in proportion to their power, and a narrow cone carries little of it:
  // these intensities leave the fill 2 % of the selections, so light sampling rarely finds it in
  // the regions it alone lights (where the baselines fail). At 1/30 of them it had 38 %, and RIS
  // recovered those regions as well as ReSTIR.
  m.spot("spot_left", {-1.0, 2.4, 1.4}, {-0.3, 1.45, 0}, 1800.0, 9, 6);
  m.spot("spot_right", {1.1, 0.5, 1.3}, {0.3, 1.1, 0}, 1350.0, 8, 5);
  m.point("fill", {0.2, 1.6, 2.2}, 0.25);
  m.view("front", {0, 1.3, 2.4}, {0, 1.3, 0}, 30);
  m.film(256, 192);
  return m.s;
}

v1::Scene ajar() {
  SceneMaker m;
  m.s.set_name("ajar");
  m.diffuse("wall", 0.65, 0.62, 0.58);
  m.diffuse("floor", 0.45, 0.35, 0.25);
  m.diffuse("door", 0.5, 0.35, 0.2);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.diffuseTexture("painting", "painting", 64, 5, 0.2, 0.45, 0.2, 0.8, 0.7, 0.5);
  // Main room x in [-2, 2], y in [0, 2.5], z in [-2, 2]; the door is in the wall x = 2.
  m.roomWithoutRightWall("floor", "wall");
  // Wall x = 2 with a door opening z in [-0.5, 0.5], y in [0, 2].
  m.quad("right_a", "wall", {0.75, 1.25, 1}, kFaceNegX, {2, 1.25, -1.25});
  m.quad("right_b", "wall", {0.75, 1.25, 1}, kFaceNegX, {2, 1.25, 1.25});
  m.quad("right_top", "wall", {0.5, 0.25, 1}, kFaceNegX, {2, 2.25, 0});
  // Door hinged at z = -0.5, opened 10 degrees into the next room: a thin wedge of light.
  {
    double a = 10.0 * M_PI / 180.0;
    auto* door = m.shape("door", "door");
    door->mutable_box();
    SceneMaker::place(door, {0.02, 0.99, 0.5}, {0, -10.0, 0},
                      {2.0 + 0.02 + 0.5 * std::sin(a), 1.0, -0.5 + 0.5 * std::cos(a)});
  }
  // Next room x in [2, 4]: five faces, the bright light on its far wall.
  m.quad("next_floor", "floor", {1, 2, 1}, kFaceUp, {3, 0, 0});
  m.quad("next_ceiling", "wall", {1, 2, 1}, kFaceDown, {3, 2.5, 0});
  m.quad("next_back", "wall", {1, 1.25, 1}, kFacePosZ, {3, 1.25, -2});
  m.quad("next_front", "wall", {1, 1.25, 1}, kFaceNegZ, {3, 1.25, 2});
  m.quad("next_far", "wall", {2, 1.25, 1}, kFaceNegX, {4, 1.25, 0});
  m.quad("bright", "emitter", {0.4, 0.4, 1}, kFaceNegX, {3.98, 1.2, 0.6});
  m.areaLight("bright_light", "bright", 400, 380, 340);
  // Painting on the back wall, and a dim fill light near the ceiling of the main room.
  m.quad("painting", "painting", {0.8, 0.6, 1}, kFacePosZ, {0.2, 1.3, -1.99});
  m.quad("fill", "emitter", {0.15, 0.15, 1}, kFaceDown, {-1.2, 2.49, 0.5});
  m.areaLight("fill_light", "fill", 10.0, 10.0, 10.0);
  m.view("room", {-1.4, 1.3, 1.8}, {0.6, 1.1, -1.2}, 50);
  m.film(256, 192);
  return m.s;
}

v1::Scene mirror() {
  SceneMaker m;
  m.s.set_name("mirror");
  m.diffuse("floor", 0.5, 0.5, 0.5);
  m.diffuse("red", 0.7, 0.15, 0.1);
  m.diffuse("blue", 0.15, 0.25, 0.7);
  m.diffuse("yellow", 0.75, 0.65, 0.15);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  auto* mir = m.s.add_materials();
  mir->set_name("mirror");
  mir->mutable_rough_conductor()->mutable_roughness()->set_value(0.08);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  m.quad("mirror", "mirror", {1.6, 1.0, 1}, kFacePosZ, {0, 1.0, -1.2});
  auto* sphere = m.shape("sphere", "red");
  sphere->mutable_sphere();
  SceneMaker::place(sphere, {0.3, 0.3, 0.3}, {0, 0, 0}, {-0.7, 0.3, 0.0});
  auto* box = m.shape("box", "blue");
  box->mutable_box();
  SceneMaker::place(box, {0.25, 0.25, 0.25}, {0, 30, 0}, {0.0, 0.25, -0.3});
  auto* cyl = m.shape("cylinder", "yellow");
  cyl->mutable_cylinder()->set_capped(true);
  SceneMaker::place(cyl, {0.2, 0.2, 0.4}, {-90, 0, 0}, {0.7, 0.4, 0.1});
  m.quad("light", "emitter", {0.5, 0.5, 1}, kFaceDown, {0, 2.6, 0.8});
  m.areaLight("top", "light", 12, 12, 12);
  m.view("front", {0.4, 1.2, 2.6}, {0, 0.7, -1.0}, 42);
  m.film(256, 192);
  return m.s;
}

// Yan et al. 2025's regime for adaptive pixel sampling: multi-bounce path tracing whose variance
// is uneven across the image. A room open to a small, very bright sun through a window: the sun
// patch and its caustic under a glass ball (found only by paths that refract onto the sun) are
// noisy; the rest of the room is lit mostly by bounced light and a dim ceiling fill. The
// parameters (a rug's texture and a glossy mirror's roughness) are seen in a minority of the
// pixels, so a sampler that finds them spends the path budget where the gradient is.
v1::Scene sunroom() {
  SceneMaker m;
  m.s.set_name("sunroom");
  m.diffuse("wall", 0.7, 0.68, 0.62);
  m.diffuse("floor", 0.45, 0.4, 0.35);
  m.diffuse("frame", 0.3, 0.25, 0.2);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.diffuseTexture("rug", "painting", 16, 23, 0.55, 0.15, 0.1, 0.85, 0.75, 0.4);
  auto* mir = m.s.add_materials();
  mir->set_name("mirror");
  mir->mutable_rough_conductor()->mutable_roughness()->set_value(0.1);
  auto* glass = m.s.add_materials();
  glass->set_name("glass");
  glass->mutable_dielectric()->set_ior(1.5);
  // Room x in [-2, 2], y in [0, 2.5], z in [-2, 2]; the window is in the wall x = 2.
  m.roomWithoutRightWall("floor", "wall");
  // Wall x = 2 around a window z in [-1.2, 0.4], y in [0.7, 1.9].
  m.quad("right_back", "wall", {0.4, 1.25, 1}, kFaceNegX, {2, 1.25, -1.6});
  m.quad("right_front", "wall", {0.8, 1.25, 1}, kFaceNegX, {2, 1.25, 1.2});
  m.quad("right_low", "wall", {0.8, 0.35, 1}, kFaceNegX, {2, 0.35, -0.4});
  m.quad("right_high", "wall", {0.8, 0.3, 1}, kFaceNegX, {2, 2.2, -0.4});
  m.quad("rug", "rug", {0.6, 0.45, 1}, kFaceUp, {-0.55, 0.003, -0.5});
  m.quad("mirror", "mirror", {0.7, 0.55, 1}, kFacePosZ, {-1.0, 1.15, -1.98});
  m.quad("mirror_frame", "frame", {0.76, 0.61, 1}, kFacePosZ, {-1.0, 1.15, -1.99});
  auto* ball = m.shape("ball", "glass");
  ball->mutable_sphere()->set_rings(48);
  SceneMaker::place(ball, {0.28, 0.28, 0.28}, {0, 0, 0}, {0.95, 0.28, -0.35});
  // The sun: small and far, low in the sky beyond the window.
  m.quad("sun", "emitter", {0.4, 0.4, 1}, kFaceNegX, {7.0, 4.2, -0.4});
  m.areaLight("sun_light", "sun", 800, 730, 600);
  m.s.mutable_lights(m.s.lights_size() - 1)->mutable_area()->set_two_sided(true);
  m.quad("fill", "emitter", {0.3, 0.3, 1}, kFaceDown, {-0.8, 2.49, 0.6});
  m.areaLight("fill_light", "fill", 4, 4, 4);
  m.view("room", {1.4, 1.4, 1.9}, {-0.6, 0.55, -1.2}, 52);
  m.film(320, 240);
  return m.s;
}

v1::Scene backlit() {
  SceneMaker m;
  m.s.set_name("backlit");
  m.diffuseTexture("object", "checker", 64, 3, 0.8, 0.75, 0.7, 0.25, 0.35, 0.55);
  auto* obj = m.shape("object", "object");
  obj->mutable_sphere();
  SceneMaker::place(obj, {0.8, 0.8, 0.8}, {0, 0, 0}, {0, 0, 0});
  auto* env = m.s.add_lights();
  env->set_name("sky");
  auto* p = env->mutable_environment()->mutable_radiance()->mutable_procedural();
  p->set_pattern("backlit_sky");
  p->set_width(512);
  p->set_height(256);
  SceneMaker::set(p->mutable_color_a(), 40, 38, 34);
  SceneMaker::set(p->mutable_color_b(), 0.25, 0.3, 0.4);
  // 16 views on a ring; view 0 looks along +z, straight into the light behind the object.
  for (int i = 0; i < 16; ++i) {
    double a = 2.0 * M_PI * i / 16.0;
    m.view("ring" + std::to_string(i), {-3.0 * std::sin(a), 0.6, -3.0 * std::cos(a)}, {0, 0, 0}, 32);
  }
  m.film(128, 128);
  return m.s;
}

// An environment map to recover (lights/sky/texels): a small sun over a sky, lighting a glossy
// probe sphere (which reflects nearly every direction into the views), a diffuse sphere and a
// diffuse box, seen from eight views that also see the sky behind them. No floor: the ground half
// of the map lights the objects from below and is seen in the probe.
v1::Scene skylight() {
  SceneMaker m;
  m.s.set_name("skylight");
  m.diffuse("clay", 0.7, 0.7, 0.7);
  m.diffuse("terracotta", 0.75, 0.4, 0.25);
  auto* probe = m.s.add_materials();
  probe->set_name("probe");
  probe->mutable_rough_conductor()->mutable_roughness()->set_value(0.05);
  auto* ball = m.shape("probe", "probe");
  ball->mutable_sphere();
  SceneMaker::place(ball, {0.6, 0.6, 0.6}, {0, 0, 0}, {-0.55, 0, 0});
  auto* clay = m.shape("clay", "clay");
  clay->mutable_sphere();
  SceneMaker::place(clay, {0.4, 0.4, 0.4}, {0, 0, 0}, {0.5, 0, 0.1});
  auto* box = m.shape("box", "terracotta");
  box->mutable_box();
  SceneMaker::place(box, {0.2, 0.2, 0.2}, {20, 35, 0}, {0.05, -0.3, -0.6});
  auto* env = m.s.add_lights();
  env->set_name("sky");
  auto* p = env->mutable_environment()->mutable_radiance()->mutable_procedural();
  p->set_pattern("sun_sky");
  p->set_width(32);
  p->set_height(16);
  SceneMaker::set(p->mutable_color_a(), 12, 11, 9);
  SceneMaker::set(p->mutable_color_b(), 0.3, 0.45, 0.75);
  for (int i = 0; i < 8; ++i) {
    const double a = 2.0 * M_PI * (i + 0.5) / 8.0;
    // Every other view looks up at the objects from below, the rest down from above: between them
    // they see the sky from the horizon to about 55 degrees up and the ground as far down.
    const bool up = i % 2 == 0;
    m.view("ring" + std::to_string(i), {-3.2 * std::sin(a), up ? -1.0 : 1.4, -3.2 * std::cos(a)}, {0, up ? 0.5 : -0.4, 0}, 55);
  }
  m.film(112, 112);
  return m.s;
}

v1::Scene tree() {
  SceneMaker m;
  m.s.set_name("tree");
  m.diffuse("ground", 0.6, 0.6, 0.6);
  m.diffuse("bark", 0.35, 0.22, 0.12);
  m.diffuse("leaves", 0.2, 0.5, 0.15);
  m.diffuse("board", 0.4, 0.4, 0.4);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("ground", "ground", {3, 3, 1}, kFaceUp, {0, 0, 0});
  // The tree's parts are flat-shaded (face_normals) and form the group "tree" (pivot: the foot of
  // the trunk), so that shape jobs can turn it (groups/tree/rotation): moving smooth-shaded meshes
  // are refused (docs/shapes.md).
  auto* trunk = m.shape("trunk", "bark");
  trunk->mutable_cylinder()->set_capped(true);
  SceneMaker::place(trunk, {0.06, 0.06, 0.5}, {-90, 0, 0}, {0, 0.5, 0});
  auto* b1 = m.shape("branch_a", "bark");
  b1->mutable_cylinder()->set_capped(true);
  SceneMaker::place(b1, {0.035, 0.035, 0.3}, {-90, 0, 40}, {-0.18, 1.05, 0});
  auto* b2 = m.shape("branch_b", "bark");
  b2->mutable_cylinder()->set_capped(true);
  SceneMaker::place(b2, {0.035, 0.035, 0.28}, {-90, 0, -35}, {0.16, 1.0, 0.05});
  const double crowns[][4] = {{0, 1.25, 0, 0.28}, {-0.38, 1.25, 0.05, 0.2}, {0.34, 1.2, 0.08, 0.2}};
  for (int i = 0; i < 3; ++i) {
    auto* c = m.shape("crown_" + std::to_string(i), "leaves");
    c->mutable_sphere()->set_rings(24);
    SceneMaker::place(c, {crowns[i][3], crowns[i][3], crowns[i][3]}, {0, 0, 0}, {crowns[i][0], crowns[i][1], crowns[i][2]});
  }
  auto* tree = m.s.add_groups();
  tree->set_name("tree");
  for (auto& shape : *m.s.mutable_shapes())
    if (shape.material() == "bark" || shape.material() == "leaves") {
      shape.set_face_normals(true);
      tree->add_shapes(shape.name());
    }
  tree->mutable_pivot()->set_y(0);
  // A small bright light casts the tree's shadow; a large light is mostly hidden behind a board.
  m.quad("small_light", "emitter", {0.08, 0.08, 1}, kFaceDown, {0.9, 2.6, 0.6});
  m.areaLight("small", "small_light", 300, 290, 270);
  m.quad("large_light", "emitter", {0.8, 0.8, 1}, kFaceDown, {-1.2, 2.8, -1.0});
  m.areaLight("large", "large_light", 6, 6, 7);
  m.quad("board", "board", {1.1, 1.1, 1}, kFaceUp, {-1.1, 2.3, -0.9});
  // Aimed down at the ground behind the tree from beyond it, where the small light throws the
  // crowns' shadows (the middle one's falls around (-0.8, 0, -0.55)); no part of the tree is in
  // view (the trunk's foot is just off the left edge), so its rotation is read from the shadow
  // alone (Wang et al. 2023, Fig. 10), through the shadow-border (secondary) term only.
  m.view("shadow", {-1.5, 2.2, -2.1}, {-1.3, 0.0, -0.62}, 30);
  m.film(256, 192);
  return m.s;
}

v1::Scene knot() {
  SceneMaker m;
  m.s.set_name("knot");
  m.diffuse("floor", 0.55, 0.55, 0.55);
  m.diffuse("knot", 0.75, 0.35, 0.2);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* k = m.shape("knot", "knot");
  k->mutable_torus_knot();
  k->set_face_normals(true);  // flat-shaded, so shape jobs can move it (shapes/knot/translation)
  SceneMaker::place(k, {0.6, 0.6, 0.6}, {0, 0, 0}, {0, 0.75, 0});
  m.spot("key", {1.2, 2.8, 1.2}, {0, 0.5, 0}, 30.0, 25, 18);
  m.point("fill_a", {-1.5, 1.0, 1.5}, 0.4);
  m.point("fill_b", {0.0, 1.5, -1.8}, 0.3);
  m.view("front", {0, 1.2, 3.0}, {0, 0.6, 0}, 40);
  m.film(256, 192);
  return m.s;
}

v1::Scene key() {
  // Wang et al. 2023, Fig. 6 (bottom): a flat-shaded key turning about the vertical in front of a
  // textured wall, lit by one small area light and a large one mostly hidden behind a board, so
  // that most light samples drawn by power go to the light that contributes least.
  SceneMaker m;
  m.s.set_name("key");
  m.diffuse("floor", 0.5, 0.5, 0.5);
  m.diffuseTexture("wall", "painting", 64, 31, 0.25, 0.3, 0.45, 0.8, 0.7, 0.5);
  m.diffuse("brass", 0.75, 0.58, 0.22);
  m.diffuse("board", 0.4, 0.4, 0.4);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  m.quad("wall", "wall", {2, 1.5, 1}, kFacePosZ, {0, 1.5, -0.8});
  // The key, upright: a round bow on top, a shaft, three teeth on one side. The parts are a few
  // millimetres apart: where two touched, their contact curve would move with the key and no
  // boundary term samples one.
  auto* bow = m.shape("bow", "brass");
  bow->mutable_cylinder()->set_capped(true);
  bow->mutable_cylinder()->set_segments(24);
  SceneMaker::place(bow, {0.2, 0.2, 0.03}, {0, 0, 0}, {0, 1.3, 0});
  auto* shaft = m.shape("shaft", "brass");
  shaft->mutable_box();
  SceneMaker::place(shaft, {0.035, 0.39, 0.025}, {0, 0, 0}, {0, 0.7, 0});
  const double teeth[][3] = {{0.4, 0.06, 0.03}, {0.52, 0.045, 0.022}, {0.64, 0.07, 0.028}};
  for (int i = 0; i < 3; ++i) {
    auto* t = m.shape("tooth_" + std::to_string(i), "brass");
    t->mutable_box();
    SceneMaker::place(t, {teeth[i][1], teeth[i][2], 0.025}, {0, 0, 0}, {0.041 + teeth[i][1], teeth[i][0], 0});
  }
  auto* group = m.s.add_groups();
  group->set_name("key");
  for (auto& shape : *m.s.mutable_shapes())
    if (shape.material() == "brass") {
      shape.set_face_normals(true);  // flat-shaded, so shape jobs can turn it (groups/key/rotation)
      group->add_shapes(shape.name());
    }
  // The small light faces the wall from in front and to the right: the key's shadow falls on the
  // wall, left of and below it. The large light sits above the scene, facing down, mostly hidden
  // by the board under it.
  m.quad("small_light", "emitter", {0.06, 0.06, 1}, kFaceNegZ, {0.7, 1.7, 2.2});
  m.areaLight("small", "small_light", 400, 380, 350);
  m.quad("large_light", "emitter", {0.9, 0.9, 1}, kFaceDown, {-1.0, 3.0, 0.6});
  m.areaLight("large", "large_light", 8, 8, 9);
  m.quad("board", "board", {1.2, 1.2, 1}, kFaceUp, {-1.0, 2.6, 0.6});
  m.view("front", {0.3, 1.1, 3.0}, {0, 1.0, -0.3}, 36);
  m.film(160, 120);
  return m.s;
}

v1::Scene spot() {
  SceneMaker m;
  m.s.set_name("spot");
  m.diffuse("floor", 0.5, 0.5, 0.5);
  m.diffuseTexture("object", "painting", 64, 21, 0.2, 0.5, 0.2, 0.8, 0.7, 0.5);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* o = m.shape("object", "object");
  o->mutable_sphere();
  SceneMaker::place(o, {0.6, 0.6, 0.6}, {0, 0, 0}, {0, 0.6, 0});
  m.spot("spot", {0.6, 2.5, 1.0}, {0.0, 0.6, 0}, 25.0, 14, 10);
  auto* amb = m.s.add_lights();
  amb->set_name("ambient");
  SceneMaker::set(amb->mutable_constant_environment()->mutable_radiance(), 0.05, 0.055, 0.06);
  m.view("front", {0, 1.0, 2.6}, {0, 0.55, 0}, 40);
  m.film(256, 192);
  return m.s;
}

// Yan et al. 2024's "rings" (Fig. 3, 6): glossy rings on a diffuse floor under a small area light.
// The rings are open tubes standing on the floor, so their glossy insides throw light onto the
// floor within them (paths of three vertices and more); their roughness sets the render's mean and
// how noisy it is.
v1::Scene rings() {
  SceneMaker m;
  m.s.set_name("rings");
  m.diffuse("floor", 0.6, 0.6, 0.6);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  auto* ring = m.s.add_materials();
  ring->set_name("rings");
  ring->mutable_rough_conductor()->mutable_roughness()->set_value(0.15);
  SceneMaker::set(ring->mutable_rough_conductor()->mutable_eta(), 0.2, 0.92, 1.1);  // gold
  SceneMaker::set(ring->mutable_rough_conductor()->mutable_k(), 3.9, 2.45, 2.14);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* a = m.shape("ring_a", "rings");
  a->mutable_cylinder();
  SceneMaker::place(a, {0.45, 0.45, 0.09}, {-90, 0, 0}, {-0.45, 0.09, 0.0});
  auto* b = m.shape("ring_b", "rings");
  b->mutable_cylinder();
  SceneMaker::place(b, {0.35, 0.35, 0.12}, {-90, 0, 0}, {0.5, 0.12, -0.25});
  m.quad("light", "emitter", {0.12, 0.12, 1}, kFaceDown, {0.6, 1.6, 0.9});
  m.areaLight("small", "light", 180, 170, 150);
  m.view("front", {0, 1.5, 1.9}, {0, 0.05, -0.1}, 45);
  m.film(160, 120);
  return m.s;
}

// A Russian-roulette scene (Yan et al. 2024, Fig. 9): a closed diffuse room lit by a small light
// behind a low partition that faces the ceiling, so the light arrives after one bounce or more
// and deep paths matter, but less with every bounce.
v1::Scene roulette() {
  SceneMaker m;
  m.s.set_name("roulette");
  m.diffuse("white", 0.78, 0.78, 0.78);
  m.diffuse("warm", 0.8, 0.6, 0.4);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("floor", "white", {1, 1, 1}, kFaceUp, {0, 0, 0});
  m.quad("ceiling", "white", {1, 1, 1}, kFaceDown, {0, 2, 0});
  m.quad("back", "warm", {1, 1, 1}, kFacePosZ, {0, 1, -1});
  m.quad("front", "white", {1, 1, 1}, kFaceNegZ, {0, 1, 1});
  m.quad("left", "white", {1, 1, 1}, kFacePosX, {-1, 1, 0});
  m.quad("right", "warm", {1, 1, 1}, kFaceNegX, {1, 1, 0});
  // The light faces the ceiling from behind the partition: the walls the camera sees are lit
  // only by the ceiling and what it lights.
  auto* wall = m.shape("partition", "white");
  wall->mutable_box();
  SceneMaker::place(wall, {0.02, 0.35, 0.9}, {0, 0, 0}, {0.45, 0.35, 0});
  m.quad("light", "emitter", {0.15, 0.15, 1}, kFaceUp, {0.75, 0.3, 0});
  m.areaLight("bulb", "light", 40, 36, 30);
  m.view("inside", {-0.85, 1.0, 0.9}, {0.2, 0.8, -0.6}, 60);
  m.film(128, 96);
  return m.s;
}

// Shape parameters: a box's pose (translation + rotation) from one image under an area light.
// Turned so that no edge lies along the pixel grid, and held 0.15 above the floor: a box resting on
// it would cut the floor at every tilt, along a contact curve no boundary term samples.
v1::Scene pose() {
  SceneMaker m;
  m.s.set_name("pose");
  m.diffuse("floor", 0.55, 0.55, 0.55);
  m.diffuse("object", 0.75, 0.45, 0.25);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* b = m.shape("object", "object");
  b->mutable_box();
  SceneMaker::place(b, {0.25, 0.2, 0.3}, {0, 35, 0}, {0, 0.35, 0});
  m.quad("lamp", "emitter", {0.25, 0.25, 1}, kFaceDown, {0.8, 2.2, 0.7});
  m.areaLight("lamp", "lamp", 40, 38, 34);
  m.view("front", {0.4, 1.4, 2.4}, {0, 0.25, 0}, 40);
  m.film(128, 96);
  return m.s;
}

// Camera parameters (calibration): a roughly known camera recovered from one image of a known
// scene. Three flat-shaded boxes of different colours and sizes, one tilted, held above a floor (a
// box resting on it would meet the floor along a contact curve no boundary term samples), under
// an area light whose shadows fall on the floor: silhouettes, creases and shadow borders all move
// on the film when the camera does.
v1::Scene calibrate() {
  SceneMaker m;
  m.s.set_name("calibrate");
  m.diffuse("floor", 0.6, 0.6, 0.6);
  m.diffuse("red", 0.7, 0.22, 0.18);
  m.diffuse("blue", 0.2, 0.35, 0.72);
  m.diffuse("yellow", 0.78, 0.66, 0.25);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* tall = m.shape("tall", "red");
  tall->mutable_box();
  SceneMaker::place(tall, {0.15, 0.35, 0.15}, {0, 25, 0}, {-0.55, 0.45, -0.35});
  auto* slab = m.shape("slab", "blue");
  slab->mutable_box();
  SceneMaker::place(slab, {0.3, 0.08, 0.2}, {0, -30, 0}, {0.45, 0.2, 0.05});
  auto* cube = m.shape("cube", "yellow");
  cube->mutable_box();
  SceneMaker::place(cube, {0.13, 0.13, 0.13}, {30, 40, 10}, {-0.05, 0.36, 0.5});
  m.quad("lamp", "emitter", {0.3, 0.3, 1}, kFaceDown, {0.9, 2.4, 0.9});
  m.areaLight("lamp", "lamp", 30, 28, 25);
  m.view("photo", {0.3, 1.5, 2.6}, {0, 0.3, 0}, 40);
  m.film(128, 96);
  return m.s;
}

// Wang et al. 2023, Fig. 13: a faceted solid (an octagonal prism, tilted) in a room, lit by 16
// spotlights around it (the paper: 17), each aimed at it so that its shadow falls on the far wall
// or floor (with 8, the shadows leave the solid's recovered shape 1.1 % of its diagonal off). The
// 16 views look outward from beside the solid at the walls: the solid is never in view, so its
// shape is read from the shadows alone (shadow-border terms only).
constexpr int kOctagonSpots = 16;

v1::Scene octagon() {
  SceneMaker m;
  m.s.set_name("octagon");
  m.diffuse("walls", 0.7, 0.7, 0.7);
  m.diffuse("solid", 0.6, 0.5, 0.4);
  m.quad("floor", "walls", {2.5, 2.5, 1}, kFaceUp, {0, 0, 0});
  m.quad("wall_back", "walls", {2.5, 1.6, 1}, kFacePosZ, {0, 1.6, -2.5});
  m.quad("wall_front", "walls", {2.5, 1.6, 1}, kFaceNegZ, {0, 1.6, 2.5});
  m.quad("wall_left", "walls", {2.5, 1.6, 1}, kFacePosX, {-2.5, 1.6, 0});
  m.quad("wall_right", "walls", {2.5, 1.6, 1}, kFaceNegX, {2.5, 1.6, 0});
  auto* solid = m.shape("solid", "solid");
  solid->mutable_cylinder()->set_segments(8);
  solid->mutable_cylinder()->set_capped(true);
  solid->set_face_normals(true);
  SceneMaker::place(solid, {0.25, 0.25, 0.16}, {-75, 20, 0}, {0, 1.1, 0});
  const double kPi = 3.14159265358979323846, cy = 1.1;
  for (int k = 0; k < kOctagonSpots; ++k) {
    // Alternately low and high, so that the shadows show the solid from below and above.
    const double a = kPi * 2.0 * double(k) / double(kOctagonSpots), r = 1.8, y = k % 2 ? 2.0 : 0.4;
    m.spot("spot_" + std::to_string(k), {r * std::cos(a), y, r * std::sin(a)}, {0, cy, 0}, 16.0, 16, 12);
    // The view stands beside the solid, on the far side from this spot, and looks away from the
    // solid at where the shadow's centre falls (the ray from the spot through the solid's centre,
    // to the first wall or the floor).
    const double dx = -std::cos(a), dy = (cy - y) / r, dz = -std::sin(a);  // per unit of horizontal run
    double t = 2.5 / std::max(std::abs(dx), std::abs(dz));
    if (dy < 0) t = std::min(t, cy / -dy);
    m.view("shadow_" + std::to_string(k), {0.75 * dx, cy, 0.75 * dz}, {t * dx, cy + t * dy, t * dz}, 55);
  }
  m.film(96, 96);
  return m.s;
}

// Wang et al. 2023, Fig. 14: a relief on a wall under a large area light seen through a window
// frame, whose bars hide parts of the light from every point of the relief.
// Six views from in front of it.
v1::Scene relief() {
  SceneMaker m;
  m.s.set_name("relief");
  m.diffuse("wall", 0.65, 0.65, 0.65);
  m.diffuse("relief", 0.75, 0.72, 0.68);
  m.diffuse("frame", 0.3, 0.25, 0.2);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  m.quad("wall", "wall", {2.5, 2.0, 1}, kFacePosZ, {0, 1.0, -0.02});
  auto* r = m.shape("relief", "relief");
  auto* h = r->mutable_heightfield();
  h->set_cells(64);
  auto* hp = h->mutable_height();
  hp->set_pattern("bumps");
  hp->set_width(128);
  hp->set_seed(5);
  SceneMaker::set(hp->mutable_color_a(), 1, 1, 1);
  SceneMaker::set(hp->mutable_color_b(), 0, 0, 0);
  SceneMaker::place(r, {1.0, 0.7, 0.25}, {0, 0, 0}, {0, 1.0, 0});
  // The light above and close to the wall, facing the relief's centre at a grazing angle (rotated
  // 116.6 degrees about x: normal (0, -0.89, -0.45)); the window frame (2 x 2 panes, parallel to
  // the light, a third of the way to the relief) hides parts of it from every point of the relief.
  // (A window wall that hid five sixths of a larger light slowed every method: 40 s of ReSTIR
  // reached 1.4 % instead of 0.7 %, and RIS stayed level with it.)
  const double tilt = 116.6, c = std::cos(tilt * 3.14159265358979323846 / 180.0), sn = std::sin(tilt * 3.14159265358979323846 / 180.0);
  m.quad("light", "emitter", {0.7, 0.5, 1}, {tilt, 0, 0}, {0, 3.0, 1.0});
  m.areaLight("window_light", "light", 12, 11.5, 10.5);
  const std::array<double, 3> centre{0, 2.33, 0.67}, up{0, c, sn};  // the frame's local y axis
  for (int i = 0; i < 3; ++i) {
    auto* v = m.shape("bar_v" + std::to_string(i), "frame");
    v->mutable_box();
    SceneMaker::place(v, {0.06, 0.41, 0.03}, {tilt, 0, 0}, {centre[0] + 0.5 * double(i - 1), centre[1], centre[2]});
    auto* h = m.shape("bar_h" + std::to_string(i), "frame");
    h->mutable_box();
    const double off = 0.35 * double(i - 1);
    SceneMaker::place(h, {0.56, 0.06, 0.03}, {tilt, 0, 0}, {centre[0], centre[1] + off * up[1], centre[2] + off * up[2]});
  }
  for (int k = 0; k < 6; ++k) {
    const double ax = -0.9 + 0.36 * double(k), ey = k % 2 ? 1.5 : 0.7;
    m.view("front_" + std::to_string(k), {ax, ey, 2.6}, {0.2 * ax, 1.0, 0}, 38);
  }
  m.film(128, 96);
  return m.s;
}

// The papers' scale (Wang et al. 2023, Table 1; Yan et al. 2025). Oxalis at 512 x 512: a plant of
// 68K triangles, lit from above left by a narrow spot, throws a detailed shadow across the left of
// a painting whose 256 x 256 texture is the parameter; a second spot lights its right, and a dim
// fill (2 % of the light selections, as in oxalis) is all that lights the rest. The plant is out
// of view: every texel the camera sees is seen unoccluded.
v1::Scene oxalisHd() {
  SceneMaker m;
  m.s.set_name("oxalis-hd");
  m.diffuse("wall", 0.6, 0.58, 0.55);
  m.diffuse("floor", 0.35, 0.3, 0.25);
  m.diffuse("leaves", 0.25, 0.5, 0.2);
  m.diffuseTexture("painting", "painting", 256, 11, 0.15, 0.4, 0.15, 0.75, 0.65, 0.45);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  m.quad("wall", "wall", {3, 2, 1}, kFacePosZ, {0, 2, -0.01});
  m.quad("painting", "painting", {0.6, 0.6, 1}, kFacePosZ, {0, 1.3, 0});
  auto* plant = m.shape("oxalis", "leaves");
  plant->mutable_plant()->set_leaves(60);
  plant->mutable_plant()->set_leaf_segments(24);
  plant->mutable_plant()->set_seed(7);
  SceneMaker::place(plant, {0.5, 0.5, 0.5}, {0, 0, 0}, {-0.2, 1.9, 0.6});
  m.spot("spot_left", {-0.6, 3.9, 1.6}, {-0.15, 1.45, 0}, 1200.0, 16, 12);
  m.spot("spot_right", {1.1, 0.5, 1.3}, {0.35, 1.1, 0}, 700.0, 9, 6);
  m.point("fill", {0.2, 1.6, 2.2}, 0.5);
  m.view("front", {0, 1.3, 2.4}, {0, 1.3, 0}, 30);
  m.film(512, 512);
  return m.s;
}

// Wang et al. 2023, Fig. 12's setting: a textured object (a torus knot standing in for the Kitty
// statue; its texture, 512 x 48 texels along and around the tube, is the parameter) seen from 32
// views around it, under a light above and a dim sky.
constexpr int kKittyViews = 32;

v1::Scene kitty() {
  SceneMaker m;
  m.s.set_name("kitty");
  m.diffuse("floor", 0.5, 0.5, 0.5);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  auto* tex = m.diffuseTexture("kitty", "painting", 512, 31, 0.7, 0.45, 0.2, 0.25, 0.35, 0.6);
  tex->mutable_diffuse()->mutable_albedo()->mutable_procedural()->set_height(48);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  auto* k = m.shape("kitty", "kitty");
  k->mutable_torus_knot()->set_segments(512);
  k->mutable_torus_knot()->set_tube_segments(32);
  SceneMaker::place(k, {0.6, 0.6, 0.6}, {-90, 0, 0}, {0, 0.75, 0});
  m.quad("lamp", "emitter", {0.3, 0.3, 1}, kFaceDown, {0.5, 2.6, 0.4});
  m.areaLight("lamp", "lamp", 30, 29, 27);
  auto* sky = m.s.add_lights();
  sky->set_name("sky");
  SceneMaker::set(sky->mutable_constant_environment()->mutable_radiance(), 0.12, 0.13, 0.15);
  const double kPi = 3.14159265358979323846;
  for (int v = 0; v < kKittyViews; ++v) {
    // Two rings of 16 around the object, the upper one turned by half a step.
    const bool upper = v % 2 == 1;
    const double a = 2 * kPi * (double(v / 2) + (upper ? 0.5 : 0.0)) / double(kKittyViews / 2);
    m.view("around_" + std::to_string(v), {2.3 * std::cos(a), upper ? 1.9 : 0.9, 2.3 * std::sin(a)}, {0, 0.75, 0}, 35);
  }
  m.film(256, 256);
  return m.s;
}

// Yan et al. 2025's setting: many high-resolution views of which a step traces a few pixels. A
// gallery room: four varnished paintings (rough plastic over their textures, the parameters), each
// under its own spotlight, a glossy floor, a dim ceiling light; 16 views at 512 x 512, four of
// each painting from around the room.
constexpr int kGalleryPaintings = 4;

v1::Scene gallery() {
  SceneMaker m;
  m.s.set_name("gallery");
  m.diffuse("walls", 0.72, 0.7, 0.66);
  m.diffuse("emitter", 0.8, 0.8, 0.8);
  auto* floor = m.s.add_materials();
  floor->set_name("floor");
  SceneMaker::set(floor->mutable_rough_plastic()->mutable_albedo()->mutable_constant(), 0.3, 0.2, 0.12);
  floor->mutable_rough_plastic()->mutable_roughness()->set_value(0.12);
  m.quad("floor", "floor", {3, 3, 1}, kFaceUp, {0, 0, 0});
  m.quad("ceiling", "walls", {3, 3, 1}, kFaceDown, {0, 3, 0});
  m.quad("wall_back", "walls", {3, 1.5, 1}, kFacePosZ, {0, 1.5, -3});
  m.quad("wall_front", "walls", {3, 1.5, 1}, kFaceNegZ, {0, 1.5, 3});
  m.quad("wall_left", "walls", {3, 1.5, 1}, kFacePosX, {-3, 1.5, 0});
  m.quad("wall_right", "walls", {3, 1.5, 1}, kFaceNegX, {3, 1.5, 0});
  m.quad("skylight", "emitter", {0.6, 0.6, 1}, kFaceDown, {0, 2.99, 0});
  m.areaLight("skylight", "skylight", 2.5, 2.5, 2.6);
  const double kPi = 3.14159265358979323846;
  // Painting k hangs on the wall facing direction (cos a, 0, sin a) from the room's centre.
  for (int k = 0; k < kGalleryPaintings; ++k) {
    const std::string name = "painting_" + std::to_string(k);
    auto* p = m.s.add_materials();
    p->set_name(name);
    auto* proc = p->mutable_rough_plastic()->mutable_albedo()->mutable_procedural();
    proc->set_pattern("painting");
    proc->set_width(64);
    proc->set_seed(uint64_t(41 + k));
    SceneMaker::set(proc->mutable_color_a(), 0.15 + 0.1 * k, 0.4, 0.2);
    SceneMaker::set(proc->mutable_color_b(), 0.8, 0.65 - 0.1 * k, 0.45);
    p->mutable_rough_plastic()->mutable_roughness()->set_value(0.25);
    const double a = 2 * kPi * double(k) / kGalleryPaintings;
    const double dx = std::cos(a), dz = std::sin(a);  // from the centre towards the wall
    // The unit quad faces +z; turn it to face the room (-dx, 0, -dz): a yaw of atan2(-dx, -dz).
    const double yaw = std::atan2(-dx, -dz) * 180.0 / kPi;
    m.quad(name, name, {0.8, 0.6, 1}, {0, yaw, 0}, {2.99 * dx, 1.6, 2.99 * dz});
    m.spot("spot_" + std::to_string(k), {1.6 * dx, 2.9, 1.6 * dz}, {3.0 * dx, 1.6, 3.0 * dz}, 10.0, 24, 18);
    for (int v = 0; v < 4; ++v) {
      // Four stand-points per painting: near and far, left and right of it, at eye heights.
      const double back = v < 2 ? 1.2 : 0.0, off = (v % 2 ? 1.0 : -1.0) * (0.5 + 0.4 * double(v / 2));
      const double ex = back * dx - off * dz, ez = back * dz + off * dx;
      m.view(name + "_view_" + std::to_string(v), {ex, 1.5 + 0.15 * double(v % 2), ez}, {2.9 * dx, 1.2, 2.9 * dz}, 45);
    }
  }
  m.film(512, 512);
  return m.s;
}

struct ZooDef {
  ZooEntry entry;
  std::function<v1::Scene()> build;
};

const std::vector<ZooDef>& zoo() {
  static const std::vector<ZooDef> defs = {
      {{"cornell", "Cornell box; wall albedos (sanity, fast)"}, cornell},
      {{"oxalis", "textured painting under two bright spots and a dim fill light"}, oxalis},
      {{"ajar", "painting in a room lit through a nearly closed door plus a dim fill"}, ajar},
      {{"mirror", "three diffuse objects in front of a glossy mirror"}, mirror},
      {{"sunroom", "a room lit by a small bright sun through a window, a glass ball and its caustic, a glossy mirror; a rug's texture and the mirror's roughness (multi-bounce path tracing, adaptive pixel sampling)"}, sunroom},
      {{"backlit", "textured sphere under an environment lit from behind, 16 views"}, backlit},
      {{"skylight", "a sky with a small sun (32x16 environment map) seen in a glossy probe, a diffuse sphere and a box, 8 views; its texels"}, skylight},
      {{"tree", "tree-like object seen only through its shadow, a small light and an occluded large light; its rotation (shape parameters)"}, tree},
      {{"knot", "torus knot under a bright spot and dim fills; its translation (shape parameters)"}, knot},
      {{"key", "a flat-shaded key turning in front of a textured wall, a small light and an occluded large light; its rotation (shape parameters)"}, key},
      {{"spot", "textured object under a bright spot and a dim ambient light; per-pixel light selection"}, spot},
      {{"rings", "glossy rings on a diffuse floor under a small area light; variance-aware roughness"}, rings},
      {{"roulette", "closed room lit indirectly, 8 bounces; Russian-roulette survival per bounce"}, roulette},
      {{"pose", "a box under an area light; its translation and rotation from one image (shape parameters)"}, pose},
      {{"calibrate", "three boxes above a floor under an area light; the camera's translation and rotation from one image (camera parameters)"}, calibrate},
      {{"octagon", "a faceted solid under 16 spotlights, seen only through its shadows on the walls (16 views); its mesh from a sphere"}, octagon},
      {{"relief", "a relief on a wall under a large light seen through a window frame (6 views); its mesh from a plane"}, relief},
      {{"oxalis-hd", "paper scale: a 68K-triangle plant's shadow on a painting, 256x256 texture (196K values), 512x512"}, oxalisHd},
      {{"kitty", "paper scale: a textured knot seen from 32 views around it, 16 per step; 512x48 texture (74K values)"}, kitty},
      {{"gallery", "paper scale: four varnished paintings and a glossy floor, 16 views at 512x512; a step traces 2.4 % of each view's pixels (adaptive)"}, gallery},
  };
  return defs;
}

}  // namespace

const std::vector<ZooEntry>& zooEntries() {
  static const std::vector<ZooEntry> entries = [] {
    std::vector<ZooEntry> e;
    for (const auto& d : zoo()) e.push_back(d.entry);
    return e;
  }();
  return entries;
}

v1::Scene zooScene(const std::string& name) {
  std::string known;
  std::vector<std::string> names;
  for (const auto& d : zoo()) {
    if (d.entry.name == name) return d.build();
    known += (known.empty() ? "" : ", ") + d.entry.name;
    names.push_back(d.entry.name);
  }
  // "unknown scene 'cornel'; did you mean 'cornell'? (zoo scenes: ...)"
  throw InputError("unknown scene '" + name + "'" + didYouMean(name, names) + " (zoo scenes: " + known + ")");
}

}  // namespace invr
