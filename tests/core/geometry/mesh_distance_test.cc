#include "core/geometry/mesh_distance.h"

#include <gtest/gtest.h>

#include <cmath>

namespace invr {
namespace {

TriangleMesh shifted(TriangleMesh m, Vec3 d) {
  for (Vec3& p : m.positions) p = p + d;
  return m;
}

TEST(MeshDistance, SameSurfaceIsZero) {
  const TriangleMesh s = makeIcosphere(3);
  EXPECT_LT(symmetricChamferDistance(s, s), 1e-6);
  // The same surface with other triangles: a grid of 8 x 8 cells against one of 3 x 3.
  EXPECT_LT(symmetricChamferDistance(makeGrid(8), makeGrid(3)), 1e-6);
}

// Two parallel squares 0.1 apart: every point of each is 0.1 from the other (its foot is inside).
// Shifted sideways too, the overhanging strips add their exact mean distance.
TEST(MeshDistance, ParallelPlanesAreTheirGap) {
  EXPECT_NEAR(symmetricChamferDistance(makeGrid(4), shifted(makeGrid(4), Vec3(0, 0, 0.1f))), 0.1, 1e-5);
  // Shifted by 0.2 along x as well: over the 0.2 x 2 strip of each square that overhangs the other
  // (a tenth of its area) the distance is sqrt(0.1^2 + s^2), s the distance past the edge, uniform
  // in [0, 0.2].
  double strip = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const double s = 0.2 * (i + 0.5) / n;
    strip += std::sqrt(0.01 + s * s) / n;
  }
  const double expected = 0.9 * 0.1 + 0.1 * strip;
  EXPECT_NEAR(symmetricChamferDistance(makeGrid(16), shifted(makeGrid(16), Vec3(0.2f, 0, 0.1f)), 16384), expected, 2e-4);
}

// Concentric spheres of radius 1 and 1.1: 0.1 apart, up to the facets' sag (an icosphere of
// subdivision 5 deviates from its sphere by less than 1e-3).
TEST(MeshDistance, ConcentricSpheres) {
  TriangleMesh a = makeIcosphere(5), b = a;
  for (Vec3& p : b.positions) p = p * 1.1f;
  EXPECT_NEAR(symmetricChamferDistance(a, b), 0.1, 2e-3);
  EXPECT_NEAR(boundingBoxDiagonal(a), 2.0 * std::sqrt(3.0), 1e-5);
}

TEST(MeshDistance, StartMeshesFaceOutwardAndHaveTheirVertexCounts) {
  for (int s = 0; s <= 3; ++s) {
    const TriangleMesh m = makeIcosphere(s);
    EXPECT_EQ(m.positions.size(), size_t(10 * (1 << (2 * s)) + 2));
    EXPECT_EQ(m.triangleCount(), size_t(20 * (1 << (2 * s))));
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      const Vec3 a = m.positions[m.indices[3 * t]], b = m.positions[m.indices[3 * t + 1]], c = m.positions[m.indices[3 * t + 2]];
      ASSERT_GT(dot(cross(b - a, c - a), a + b + c), 0.f) << "subdivision " << s << " triangle " << t;
    }
  }
  const TriangleMesh g = makeGrid(5);
  EXPECT_EQ(g.positions.size(), 36u);
  EXPECT_EQ(g.triangleCount(), 50u);
  for (size_t t = 0; t < g.triangleCount(); ++t) {
    const Vec3 a = g.positions[g.indices[3 * t]], b = g.positions[g.indices[3 * t + 1]], c = g.positions[g.indices[3 * t + 2]];
    EXPECT_GT(cross(b - a, c - a).z, 0.f);
  }
}

}  // namespace
}  // namespace invr
