// Bad scene input: every mistake gives an InputError naming the field or file, never a crash.
#include "core/scene/scene_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "core/error.h"
#include "core/image/procedural.h"
#include "core/scene/zoo.h"
#include "test_util.h"

namespace invr {
namespace {

std::filesystem::path tmpDir() {
  auto dir = std::filesystem::temp_directory_path() / ("invr_scene_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

std::string errorOf(const std::string& sceneJson, const AssetResolver& assets = {}) {
  try {
    auto job = parseJobJson("{\"scene\": " + sceneJson + "}", "job.json");
    buildJobScene(job, assets);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string withShape(const std::string& shapeJson, const std::string& extraLights = "") {
  return R"({"materials": [{"name": "m", "diffuse": {}}], "shapes": [)" + shapeJson + R"(], "lights": [)" + extraLights +
         R"(], "views": [{"eye": {"z": 3}, "target": {}}]})";
}

#define EXPECT_MENTIONS(err, part) EXPECT_NE((err).find(part), std::string::npos) << "error was: " << (err)

TEST(SceneBuilder, EveryZooSceneBuilds) {
  for (const auto& e : zooEntries()) {
    auto scene = buildScene(zooScene(e.name));
    EXPECT_FALSE(scene->meshes.empty()) << e.name;
    EXPECT_FALSE(scene->lights.empty()) << e.name;
    EXPECT_FALSE(scene->cameras.empty()) << e.name;
  }
  EXPECT_EQ(buildScene(zooScene("backlit"))->cameras.size(), 16u);
}

TEST(SceneBuilder, UnknownZooNameListsKnownNames) {
  try {
    zooScene("cornel");
    FAIL();
  } catch (const InputError& e) {
    std::string m = e.what();
    EXPECT_MENTIONS(m, "cornel'");
    EXPECT_MENTIONS(m, "cornell, oxalis");
  }
}

TEST(SceneBuilder, MissingMeshFile) {
  std::string e = errorOf(withShape(R"({"name": "s", "material": "m", "mesh": {"path": "nope.obj"}})"));
  EXPECT_MENTIONS(e, "scene.shapes[0] (s)");
  EXPECT_MENTIONS(e, "nope.obj");
  EXPECT_MENTIONS(e, "not found");
}

TEST(SceneBuilder, EmptyAndNonManifoldMeshes) {
  auto dir = tmpDir();
  std::ofstream(dir / "empty.obj") << "# nothing\n";
  // Three triangles sharing the edge (1,2): non-manifold.
  std::ofstream(dir / "fan.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 2 3\nf 2 3 4\nf 2 3 5\n";
  AssetResolver assets;
  assets.baseDir = dir;
  std::string e = errorOf(withShape(R"({"name": "e", "material": "m", "mesh": {"path": "empty.obj"}})"), assets);
  EXPECT_MENTIONS(e, "scene.shapes[0] (e)");
  EXPECT_MENTIONS(e, "empty");
  e = errorOf(withShape(R"({"name": "f", "material": "m", "mesh": {"path": "fan.obj"}})"), assets);
  EXPECT_MENTIONS(e, "scene.shapes[0] (f)");
  EXPECT_MENTIONS(e, "non-manifold");
}

TEST(SceneBuilder, NanInTransform) {
  std::string e = errorOf(withShape(R"({"name": "q", "material": "m", "quad": {}, "transform": {"translate": {"x": "NaN"}}})"));
  EXPECT_MENTIONS(e, "scene.shapes[0] (q).transform.translate");
  EXPECT_MENTIONS(e, "finite");
  e = errorOf(withShape(R"({"name": "q", "material": "m", "quad": {}, "transform": {"scale": {"x": 0, "y": 1, "z": 1}}})"));
  EXPECT_MENTIONS(e, "transform.scale");
}

TEST(SceneBuilder, ZeroAreaLight) {
  std::string e = errorOf(withShape(
      R"({"name": "lamp", "material": "m", "quad": {}, "transform": {"scale": {"x": 1e-30, "y": 1e-30, "z": 1}}})",
      R"({"name": "l", "area": {"shape": "lamp", "radiance": {"r": 1}}})"));
  EXPECT_MENTIONS(e, "scene.shapes[0] (lamp)");
  EXPECT_MENTIONS(e, "zero area");
}

TEST(SceneBuilder, TextureThatFailsToLoad) {
  auto dir = tmpDir();
  std::ofstream(dir / "broken.png") << "garbage";
  AssetResolver assets;
  assets.baseDir = dir;
  for (const char* file : {"broken.png", "absent.png"}) {
    std::string scene = std::string(R"({"materials": [{"name": "m", "diffuse": {"albedo": {"image": {"path": ")") + file +
                        R"("}}}}], "shapes": [{"name": "q", "material": "m", "quad": {}}], "views": [{"eye": {"z": 3}, "target": {}}]})";
    std::string e = errorOf(scene, assets);
    EXPECT_MENTIONS(e, "scene.materials[0] (m).diffuse.albedo.image");
    EXPECT_MENTIONS(e, file);
  }
}

// The relief primitive: a grid raised by its image. A horizontal "gradient" from 0 to 1 over 4
// texels has texel centres at u = 0.125 ... 0.875, so bilinear lookup gives height u clamped to
// that range; nothing else may change the heights.
TEST(SceneBuilder, HeightfieldRaisesAGridByItsImage) {
  auto job = parseJobJson("{\"scene\": " + withShape(R"({"name": "h", "material": "m", "heightfield": {"cells": 8, "height":
      {"pattern": "gradient", "width": 4, "color_a": {}, "color_b": {"r": 1, "g": 1, "b": 1}}}})") + "}", "job.json");
  auto scene = buildJobScene(job, {});
  ASSERT_EQ(scene->meshes.size(), 1u);
  const TriangleMesh& m = scene->meshes[0];
  EXPECT_EQ(m.positions.size(), 81u);
  EXPECT_EQ(m.triangleCount(), 128u);
  ASSERT_EQ(m.uvs.size(), m.positions.size());
  EXPECT_TRUE(m.normals.empty());  // flat-shaded
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const float u = 0.5f * (m.positions[i].x + 1.f);
    EXPECT_NEAR(m.uvs[i].x, u, 1e-6f);
    EXPECT_NEAR(m.positions[i].z, std::clamp(u, 0.125f, 0.875f), 1e-5f) << "vertex " << i;
  }
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "h", "material": "m", "heightfield": {"cells": 2000, "height": {"pattern": "bumps"}}})")),
                  "scene.shapes[0] (h).heightfield.cells");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "h", "material": "m", "heightfield": {}})")), "heightfield.height");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "h", "material": "m", "heightfield": {"height": {"pattern": "hills"}}})")),
                  "unknown pattern 'hills'");
}

// The plant primitive from JSON: the documented defaults (100 leaves at 18 segments: 64,200
// triangles), flat-shaded, and its bad sizes named.
TEST(SceneBuilder, PlantFromJsonHasItsDefaultsAndNamesBadSizes) {
  auto job = parseJobJson("{\"scene\": " + withShape(R"({"name": "p", "material": "m", "plant": {"seed": 3}})") + "}", "job.json");
  auto scene = buildJobScene(job, {});
  ASSERT_EQ(scene->meshes.size(), 1u);
  EXPECT_EQ(scene->meshes[0].triangleCount(), 64200u);
  EXPECT_TRUE(scene->meshes[0].normals.empty());
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "p", "material": "m", "plant": {"leaf_segments": 2}})")), "scene.shapes[0] (p).plant.leaf_segments");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "p", "material": "m", "plant": {"leaves": 200000}})")), "scene.shapes[0] (p).plant.leaves");
}

TEST(SceneBuilder, BumpsSpanTheirTwoColours) {
  ProceduralSpec spec;
  spec.pattern = "bumps";
  spec.width = spec.height = 48;
  spec.seed = 5;
  spec.a = Rgb(1.f);
  spec.b = Rgb(0.f);
  const Image im = makeProceduralImage(spec);
  float lo = 1e9f, hi = -1e9f;
  for (float v : im.data()) lo = std::min(lo, v), hi = std::max(hi, v);
  EXPECT_NEAR(lo, 0.f, 1e-6f);
  EXPECT_NEAR(hi, 1.f, 1e-6f);
  spec.seed = 6;  // another seed, other hills
  EXPECT_NE(makeProceduralImage(spec).data(), im.data());
}

TEST(SceneBuilder, ReferencesAndValuesAreChecked) {
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "q", "material": "wood", "quad": {}})")), "unknown material 'wood'");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "q", "material": "m", "quad": {}})",
                                    R"({"name": "l", "area": {"shape": "ghost"}})")), "scene.lights[0] (l).area.shape");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "q", "material": "m"})")), "no geometry");
  EXPECT_MENTIONS(errorOf(withShape(R"({"name": "q", "material": "m", "quad": {}})",
                                    R"({"name": "p", "point": {"intensity": {"r": -1}}})")), "negative");
  EXPECT_MENTIONS(errorOf(R"({"materials": [{"name": "m", "rough_conductor": {"roughness": {"value": 0}}}],
      "shapes": [{"name": "q", "material": "m", "quad": {}}], "views": [{"eye": {"z": 3}, "target": {}}]})"), "roughness");
  EXPECT_MENTIONS(errorOf(R"({"materials": [{"name": "m", "diffuse": {}}],
      "shapes": [{"name": "q", "material": "m", "quad": {}}], "views": []})"), "scene.views");
  EXPECT_MENTIONS(errorOf(R"({"materials": [{"name": "m", "diffuse": {}}],
      "shapes": [{"name": "q", "material": "m", "quad": {}}], "views": [{"eye": {"z": 1}, "target": {"z": 1}}]})"), "scene.views[0].target");
  // Stored reservoirs keep their view in 16 bits.
  std::string views;
  for (int i = 0; i < 65536; ++i) views += std::string(i ? "," : "") + R"({"eye": {"z": 3}, "target": {}})";
  EXPECT_MENTIONS(errorOf(R"({"materials": [{"name": "m", "diffuse": {}}],
      "shapes": [{"name": "q", "material": "m", "quad": {}}], "views": [)" + views + "]}"), "at most 65535 camera views");
}

}  // namespace
}  // namespace invr
