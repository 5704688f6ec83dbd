#include "core/geometry/embree_scene.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace invr
