#include "core/geometry/ray_queue.h"

#include <gtest/gtest.h>

#include <cmath>

namespace invr {
namespace {

// A queue's hits are each ray's own: camera-like fans of rays from one eye over a sphere, a box
// and a quad, queued in batches of every size (so packets of 1 to 8 rays occur), against
// intersect() ray by ray. Packets and single rays share Embree's triangle test, but Embree's
// kernels may round a ray grazing an edge differently (measured: 1 ray in 262,144 of camera
// rays over 2,000 random triangles named the neighbouring triangle): at most one such ray is
// allowed here, among 9,000.
TEST(CameraRayQueue, AnswersAsSingleRaysDo) {
  std::vector<TriangleMesh> meshes = {makeSphere(24), makeBox(), makeQuad()};
  meshes[1].transform(Affine::translate({1.5f, 0.2f, -0.5f}));
  meshes[2].transform(Affine::translate({-1.f, -0.5f, -1.3f}));
  EmbreeScene accel;
  accel.build(meshes);
  const Vec3 eye(0.1f, 0.2f, 4.f);
  CameraRayQueue queue;
  int rays = 0, hits = 0, disagreements = 0;
  for (int batch = 0; batch < 300; ++batch) {
    queue.clear();
    const int n = 1 + (batch * 7) % CameraRayQueue::kCapacity;
    for (int i = 0; i < n; ++i) {
      const int k = batch * CameraRayQueue::kCapacity + i;  // a film position on a 120 x 160 grid
      const float fx = float(k % 120) / 120.f - 0.5f, fy = float((k / 120) % 160) / 160.f - 0.5f;
      EXPECT_EQ(queue.push(eye, normalize(Vec3(0.8f * fx, 0.8f * fy, -1.f))), i);
    }
    ASSERT_EQ(queue.size(), n);
    queue.trace(accel);
    for (int i = 0; i < n; ++i, ++rays) {
      RayHit single{};
      const bool found = accel.intersect(queue.origin(i), queue.direction(i), 0.f, std::numeric_limits<float>::infinity(), single);
      if (found != queue.found(i) || (found && (single.mesh != queue.hit(i).mesh || single.tri != queue.hit(i).tri))) {
        ++disagreements;
        continue;
      }
      if (!found) continue;
      ++hits;
      const RayHit& h = queue.hit(i);
      EXPECT_NEAR(h.t, single.t, 1e-5f * single.t) << "ray " << rays;
      EXPECT_NEAR(h.b1, single.b1, 1e-5f) << "ray " << rays;
      EXPECT_NEAR(h.b2, single.b2, 1e-5f) << "ray " << rays;
    }
  }
  EXPECT_LE(disagreements, 1);
  // Both answers occur often enough for the comparison to mean something.
  EXPECT_GT(hits, rays / 5);
  EXPECT_LT(hits, rays * 4 / 5);
}

}  // namespace
}  // namespace invr
