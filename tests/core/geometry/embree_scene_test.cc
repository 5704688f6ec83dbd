#include "core/geometry/embree_scene.h"

#include <gtest/gtest.h>

#include <limits>

namespace invr {
namespace {

TEST(EmbreeScene, IntersectsAndRefitsAfterVerticesMove) {
  std::vector<TriangleMesh> meshes = {makeQuad(), makeQuad()};
  meshes[1].transform(Affine::translate({0, 0, -2}));
  EmbreeScene accel;
  accel.build(meshes, {true, false});
  RayHit hit;
  ASSERT_TRUE(accel.intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100, hit));
  EXPECT_EQ(hit.mesh, 0u);
  EXPECT_NEAR(hit.t, 5.f, 1e-5f);
  // Barycentrics reproduce the hit point.
  const TriangleMesh& m = meshes[0];
  Vec3 p = m.positions[m.indices[3 * hit.tri]] * (1 - hit.b1 - hit.b2) + m.positions[m.indices[3 * hit.tri + 1]] * hit.b1 +
           m.positions[m.indices[3 * hit.tri + 2]] * hit.b2;
  EXPECT_NEAR(p.x, 0.2f, 1e-5f);
  EXPECT_NEAR(p.y, 0.3f, 1e-5f);

  // Move the dynamic quad up by 1.5: the same ray now hits it 1.5 earlier.
  auto moved = meshes[0].positions;
  for (auto& v : moved) v.z += 1.5f;
  accel.updatePositions(0, moved);
  ASSERT_TRUE(accel.intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100, hit));
  EXPECT_NEAR(hit.t, 3.5f, 1e-5f);
  // Move it sideways out of the ray: the static quad behind is hit.
  for (auto& v : moved) v.x += 10.f;
  accel.updatePositions(0, moved);
  ASSERT_TRUE(accel.intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100, hit));
  EXPECT_EQ(hit.mesh, 1u);
  EXPECT_NEAR(hit.t, 7.f, 1e-5f);
  EXPECT_TRUE(accel.occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));
  EXPECT_FALSE(accel.occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 6.9f));
}

// A packet's answers are each ray's own: random segments and rays through a few solids, packets
// of every size, against one query per ray.
TEST(EmbreeScene, ShadowPacketsAnswerAsSingleRaysDo) {
  std::vector<TriangleMesh> meshes = {makeSphere(24), makeBox(), makeQuad()};
  meshes[1].transform(Affine::translate({1.5f, 0.2f, -0.5f}));
  meshes[2].transform(Affine::translate({-1.f, -0.5f, 0.3f}));
  EmbreeScene accel;
  accel.build(meshes);
  uint64_t state = 12345;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return float(state >> 40) * 0x1p-24f * 6.f - 3.f;
  };
  int blockedCount = 0, rays = 0;
  for (int round = 0; round < 2000; ++round) {
    const int n = 1 + round % EmbreeScene::kPacket;
    Vec3 o[EmbreeScene::kPacket], d[EmbreeScene::kPacket];
    float tmax[EmbreeScene::kPacket];
    bool blocked[EmbreeScene::kPacket];
    const Vec3 origin(uniform(), uniform(), uniform());  // a shading point's rays share their origin
    for (int i = 0; i < n; ++i) {
      o[i] = round % 2 ? origin : Vec3(uniform(), uniform(), uniform());
      Vec3 to(uniform(), uniform(), uniform());
      d[i] = normalize(to - o[i]);
      tmax[i] = i % 3 == 0 ? std::numeric_limits<float>::infinity() : length(to - o[i]);
    }
    accel.occludedPacket(n, o, d, tmax, blocked);
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(blocked[i], accel.occluded(o[i], d[i], 0.f, tmax[i])) << "round " << round << " ray " << i;
      blockedCount += blocked[i];
      ++rays;
    }
  }
  // Both answers occur often enough for the comparison to mean something.
  EXPECT_GT(blockedCount, rays / 5);
  EXPECT_LT(blockedCount, rays * 4 / 5);
}

}  // namespace
}  // namespace invr
