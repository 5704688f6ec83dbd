// Shape motion: the maps, their exact derivatives (velocity fields against central differences in
// double), vertices, normals and the BVH following a parameter write, groups and input errors.
#include "core/scene/shape_motion.h"

#include <gtest/gtest.h>

#include "core/diff/parameters.h"
#include "core/error.h"
#include "core/math/rng.h"
#include "test_util.h"

namespace invr {
namespace {

using test::sceneFromJson;

// Two boxes, b in group g with a sphere s; a quad floor that never moves; an area light.
const char* kScene = R"({
  "materials": [{"name": "m", "diffuse": {}}],
  "shapes": [
    {"name": "a", "box": {}, "material": "m", "transform": {"translate": {"x": -2}}},
    {"name": "b", "box": {}, "material": "m", "transform": {"translate": {"x": 2}, "scale": {"x": 0.5, "y": 0.5, "z": 0.5}},
     "pivot": {"x": 2, "y": -0.5}},
    {"name": "s", "sphere": {"rings": 8}, "material": "m", "transform": {"translate": {"y": 2}}},
    {"name": "floor", "quad": {}, "material": "m", "transform": {"translate": {"z": -3}, "scale": {"x": 5, "y": 5, "z": 1}}},
    {"name": "lamp", "quad": {}, "material": "m", "transform": {"translate": {"z": 5}}}],
  "groups": [{"name": "g", "shapes": ["b", "s"]}],
  "lights": [{"name": "l", "area": {"shape": "lamp", "radiance": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 10}, "target": {}}]})";

Affine3d perturbed(RigidMotion m, Vec3 pivot, int k, double h) {
  if (k < 3) m.translation[k] += float(h);
  else if (k < 6) m.rotationDegrees[k - 3] += float(h);
  else m.scale += float(h);
  return motionMap(m, pivot);
}

TEST(ShapeMotion, DerivativeMatchesCentralDifferences) {
  RigidMotion m;
  m.translation = Vec3(0.3f, -1.f, 2.f);
  m.rotationDegrees = Vec3(20.f, -35.f, 50.f);
  m.scale = 1.25f;
  Vec3 pivot(0.5f, 1.f, -2.f);
  // h is a power of two so the float parameters move by exactly h.
  const double h = 1.0 / 64;
  for (int k = 0; k < RigidMotion::kComponents; ++k) {
    Affine3d d = motionDerivative(m, pivot, k), plus = perturbed(m, pivot, k, h), minus = perturbed(m, pivot, k, -h);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) {
        double fd = (plus.m[i][j] - minus.m[i][j]) / (2 * h);
        // Central differences of sines and cosines err by O(h^2 (pi/180)^2 ...): far below 1e-6.
        EXPECT_NEAR(d.m[i][j], fd, 1e-6 * (1 + std::abs(fd))) << "component " << k << " entry " << i << "," << j;
      }
  }
}

TEST(ShapeMotion, MapIsAboutThePivot) {
  RigidMotion m;
  m.rotationDegrees = Vec3(0, 0, 90);
  m.scale = 2;
  Vec3 pivot(1, 1, 0);
  Vec3 q = motionMap(m, pivot).point(Vec3(2, 1, 0));  // one unit along x from the pivot
  EXPECT_NEAR(q.x, 1.f, 1e-6f);
  EXPECT_NEAR(q.y, 3.f, 1e-6f);  // rotated to +y and doubled
  EXPECT_NEAR(motionMap(m, pivot).point(pivot).x, 1.f, 1e-6f);
  Affine3d a = motionMap(m, pivot), id = a * a.inverse();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(id.m[i][j], i == j ? 1.0 : 0.0, 1e-12);
}

// The velocity field of every registered component against central differences of the vertices a
// parameter write produces (float vertices: h = 1/64, tolerance from float rounding of positions
// of size ~4 divided by 2h).
TEST(ShapeMotion, VelocityFieldsMatchMovedVertices) {
  auto scene = sceneFromJson(kScene);
  ParameterRegistry reg;
  for (const char* p : {"shapes/b/translation", "shapes/b/rotation", "shapes/b/scale", "groups/g/rotation", "groups/g/translation",
                        "groups/g/scale"})
    reg.add(*scene, p);
  ASSERT_EQ(reg.movingMeshes(), (std::vector<uint32_t>{1, 2}));
  std::vector<float> theta = reg.read(*scene);
  ASSERT_EQ(theta.size(), 3u + 3 + 1 + 3 + 3 + 1);
  EXPECT_EQ(theta[6], 1.f);  // shapes/b/scale starts at 1
  // A pose away from the rest pose, so the composition is exercised.
  const std::vector<float> pose = {0.25f, -0.5f, 0.125f, 10, 20, -30, 1.5f, -15, 5, 25, 0.5f, 0.25f, -1, 0.75f};
  reg.write(pose, *scene);
  for (uint32_t mesh : reg.movingMeshes()) {
    for (const auto& f : reg.shapeFields(mesh)) {
      const float h = 1.f / 64;
      auto plus = pose, minus = pose;
      plus[f.index] += h;
      minus[f.index] -= h;
      reg.write(plus, *scene);
      auto pp = scene->meshes[mesh].positions;
      reg.write(minus, *scene);
      auto pm = scene->meshes[mesh].positions;
      reg.write(pose, *scene);
      const auto& p0 = scene->meshes[mesh].positions;
      double worst = 0;
      for (size_t i = 0; i < p0.size(); ++i) {
        Vec3 analytic = scene->motion.pointVelocity(mesh, f.field, p0[i]);
        Vec3 fd = (pp[i] - pm[i]) / (2 * h);
        // Rotations: the second-order FD error is |v| (h pi/180)^2 / 6, negligible; float rounding
        // of positions (|p| < 8: 1e-6) over 2h gives ~1e-4.
        worst = std::max(worst, double(length(analytic - fd)) / (1.0 + length(fd)));
      }
      EXPECT_LT(worst, 2e-4) << scene->meshNames[mesh] << " theta[" << f.index << "] field " << f.field;
    }
  }
}

TEST(ShapeMotion, NormalVelocityMatchesMovedFaceNormals) {
  auto scene = sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "shapes/a/rotation");
  reg.add(*scene, "shapes/a/scale");
  std::vector<float> pose = {30, -20, 10, 0.8f};
  reg.write(pose, *scene);
  for (const auto& f : reg.shapeFields(0)) {
    const float h = 1.f / 64;
    auto plus = pose, minus = pose;
    plus[f.index] += h;
    minus[f.index] -= h;
    reg.write(plus, *scene);
    Vec3 np = scene->faceNormal(0, 3);
    reg.write(minus, *scene);
    Vec3 nm = scene->faceNormal(0, 3);
    reg.write(pose, *scene);
    Vec3 analytic = scene->motion.normalVelocity(0, f.field, scene->faceNormal(0, 3));
    Vec3 fd = (np - nm) / (2 * h);
    EXPECT_LT(length(analytic - fd), 1e-4f) << "field " << f.field;
  }
}

TEST(ShapeMotion, WriteMovesVerticesNormalsAndTheBvh) {
  auto scene = sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "shapes/a/translation");
  reg.add(*scene, "shapes/s/rotation");
  const auto restA = scene->meshes[0].positions;
  const auto restNormals = scene->meshes[2].normals;
  ASSERT_FALSE(restNormals.empty());
  uint64_t version = scene->geometryVersion();
  // Box a: centre (-2, 0, 0). A ray down -z at x = -2 hits it; after moving it by +3 in y, it misses.
  SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(Vec3(-2, 0, 9), Vec3(0, 0, -1), hit));
  EXPECT_EQ(hit.mesh, 0u);
  reg.write({0, 3, 0, 0, 0, 90}, *scene);
  EXPECT_GT(scene->geometryVersion(), version);
  for (size_t i = 0; i < restA.size(); ++i) EXPECT_EQ(scene->meshes[0].positions[i].y, restA[i].y + 3.f);
  ASSERT_TRUE(scene->intersect(Vec3(-2, 0, 9), Vec3(0, 0, -1), hit));
  EXPECT_NE(hit.mesh, 0u) << "the BVH still has box a at its rest pose";
  ASSERT_TRUE(scene->intersect(Vec3(-2, 3, 9), Vec3(0, 0, -1), hit));
  EXPECT_EQ(hit.mesh, 0u);
  // The sphere's vertex normals turned 90 degrees about z with it: (x, y) -> (-y, x).
  const auto& n = scene->meshes[2].normals;
  for (size_t i = 0; i < n.size(); i += 7) {
    EXPECT_NEAR(n[i].x, -restNormals[i].y, 1e-5f);
    EXPECT_NEAR(n[i].y, restNormals[i].x, 1e-5f);
  }
  // Writing the same pose again moves nothing.
  version = scene->geometryVersion();
  reg.write({0, 3, 0, 0, 0, 90}, *scene);
  EXPECT_EQ(scene->geometryVersion(), version);
  // Back to the rest pose exactly: vertices are recomputed from the rest pose, never accumulated.
  reg.write({0, 0, 0, 0, 0, 0}, *scene);
  for (size_t i = 0; i < restA.size(); ++i) EXPECT_EQ(scene->meshes[0].positions[i], restA[i]);
}

// A snapshot of the pose recalls the geometry after it moved on: surface points, normals and
// shadow segments in the snapshot equal those of the scene moved back to that pose (box a, the
// grouped sphere with its vertex normals, segments through the moving and the static meshes).
TEST(ShapeMotion, PoseSnapshotRecallsTheGeometryItWasTakenIn) {
  auto scene = sceneFromJson(kScene);
  ParameterRegistry reg;
  reg.add(*scene, "shapes/a/translation");
  reg.add(*scene, "groups/g/rotation");
  const std::vector<float> then{0.4f, -0.3f, 0.2f, 10.f, -20.f, 35.f}, now{-0.5f, 0.6f, 0.f, -15.f, 5.f, -40.f};
  reg.write(then, *scene);
  const PoseSnapshot pose = scene->pose();
  ASSERT_EQ(pose.meshes.size(), 3u);  // a, b and s
  struct Query {
    uint32_t mesh, tri;
    float b1, b2;
  };
  std::vector<Query> points;
  std::vector<std::pair<Vec3, Vec3>> segments;
  Sampler rng(RngKey{21, 0, 0, 0, 0});
  for (uint32_t m : {0u, 2u, 3u})
    for (int i = 0; i < 40; ++i) {
      float u = rng.next1D(), v = rng.next1D();
      if (u + v > 1.f) u = 1.f - u, v = 1.f - v;
      points.push_back({m, uint32_t(rng.next1D() * float(scene->meshes[m].triangleCount())) % uint32_t(scene->meshes[m].triangleCount()), u, v});
    }
  for (int i = 0; i < 400; ++i) {
    // Every fourth one ends below the (static) floor.
    Vec3 a(6.f * rng.next1D() - 3.f, 6.f * rng.next1D() - 3.f, 4.5f), b(6.f * rng.next1D() - 3.f, 6.f * rng.next1D() - 3.f, i % 4 ? -2.9f : -3.5f);
    segments.push_back({a, b});
  }
  auto observe = [&](auto&& surface, auto&& blocked) {
    std::vector<SurfaceHit> hits;
    for (const Query& q : points) hits.push_back(surface(q));
    std::vector<int> occluded;
    for (auto [a, b] : segments) occluded.push_back(blocked(a, b) ? 1 : 0);
    return std::make_pair(hits, occluded);
  };
  auto expected = observe([&](const Query& q) { return scene->surfaceAt(q.mesh, q.tri, q.b1, q.b2); },
                          [&](Vec3 a, Vec3 b) {
                            Vec3 d;
                            float t;
                            return scene->occludedSegment(a, b, d, t);
                          });
  reg.write(now, *scene);
  ASSERT_NE(scene->geometryVersion(), pose.version);
  auto recalled = observe([&](const Query& q) { return scene->surfaceAt(pose, q.mesh, q.tri, q.b1, q.b2); },
                          [&](Vec3 a, Vec3 b) { return scene->occludedSegment(pose, a, b); });
  auto moved = observe([&](const Query& q) { return scene->surfaceAt(q.mesh, q.tri, q.b1, q.b2); },
                       [&](Vec3 a, Vec3 b) {
                         Vec3 d;
                         float t;
                         return scene->occludedSegment(a, b, d, t);
                       });
  int blockedThen = 0, changed = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const SurfaceHit &e = expected.first[i], &r = recalled.first[i];
    EXPECT_EQ(e.p, r.p) << "point " << i;
    EXPECT_EQ(e.ng, r.ng) << "point " << i;
    EXPECT_NEAR(length(e.ns - r.ns), 0.f, 1e-6f) << "point " << i;
  }
  for (size_t i = 0; i < segments.size(); ++i) {
    EXPECT_EQ(expected.second[i], recalled.second[i]) << "segment " << i;
    blockedThen += expected.second[i];
    changed += expected.second[i] != moved.second[i];
  }
  // The segments exercise both answers, and the motion changed some of them.
  EXPECT_GT(blockedThen, 20);
  EXPECT_LT(blockedThen, 380);
  EXPECT_GT(changed, 10);
  // The current pose's snapshot is the current geometry.
  const PoseSnapshot here = scene->pose();
  for (size_t i = 0; i < segments.size(); ++i)
    EXPECT_EQ(scene->occludedSegment(here, segments[i].first, segments[i].second), moved.second[i] == 1);
}

TEST(ShapeMotion, PivotsDefaultToBoundsCentresAndCanBeSet) {
  auto scene = sceneFromJson(kScene);
  EXPECT_NEAR(scene->meshPivot[0].x, -2.f, 1e-6f);   // box a's centre
  EXPECT_NEAR(scene->meshPivot[1].y, -0.5f, 1e-6f);  // b's pivot as given
  ASSERT_EQ(scene->groups.size(), 1u);
  // g = b ([1.5, 2.5] x [-0.5, 0.5]) and the sphere at y = 2 (radius 1): x in [-1, 2.5], y in [-0.5, 3].
  EXPECT_NEAR(scene->groups[0].pivot.x, 0.75f, 1e-5f);
  EXPECT_NEAR(scene->groups[0].pivot.y, 1.25f, 1e-5f);
  EXPECT_EQ(scene->meshGroup, (std::vector<int>{-1, 0, 0, -1, -1}));
}

#define EXPECT_THROWS_MENTIONING(stmt, part)                                              \
  try {                                                                                  \
    stmt;                                                                                \
    ADD_FAILURE() << "no error";                                                         \
  } catch (const InputError& e) {                                                        \
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << "error: " << e.what(); \
  }

TEST(ShapeMotion, BadNamesAndGroupsAreRefusedByName) {
  auto scene = sceneFromJson(kScene);
  ParameterRegistry reg;
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/nope/translation"), "no shape named 'nope'");
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "groups/nope/rotation"), "no group named 'nope'");
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/a/shear"), "unknown shape property 'shear'");
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/lamp/translation"), "moving emitters");
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/a"), "shapes/<name>/translation");
  reg.add(*scene, "shapes/a/scale");
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/a/scale"), "listed twice");
  ParameterOptions o;
  o.lower = 0.f;
  EXPECT_THROWS_MENTIONING(reg.add(*scene, "shapes/b/scale", o), "lower bound of a scale must be positive");

  auto groupError = [](const std::string& groups) {
    try {
      sceneFromJson(R"({"materials": [{"name": "m", "diffuse": {}}], "shapes": [{"name": "a", "box": {}, "material": "m"},
        {"name": "b", "box": {}, "material": "m"}], "groups": )" + groups + R"(, "views": [{"eye": {"z": 3}, "target": {}}]})");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(groupError(R"([{"name": "g", "shapes": ["zz"]}])").find("unknown shape 'zz'"), std::string::npos);
  EXPECT_NE(groupError(R"([{"name": "g", "shapes": []}])").find("at least one shape"), std::string::npos);
  EXPECT_NE(groupError(R"([{"name": "g", "shapes": ["a"]}, {"name": "h", "shapes": ["a"]}])").find("already in group 'g'"), std::string::npos);
  EXPECT_NE(groupError(R"([{"name": "g", "shapes": ["a"]}, {"name": "g", "shapes": ["b"]}])").find("duplicate group name"), std::string::npos);
  EXPECT_NE(groupError(R"([{"shapes": ["a"]}])").find("every group needs a name"), std::string::npos);
}

}  // namespace
}  // namespace invr
