#include "core/geometry/mesh.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <map>

#include "core/error.h"
#include "core/geometry/edge_topology.h"
#include "test_util.h"

namespace invr {
namespace {

// Closed, consistently oriented: every directed edge appears once and its reverse once.
void expectClosedOriented(const TriangleMesh& m, const std::string& what) {
  std::map<std::array<uint32_t, 3>, uint32_t> ids;
  std::vector<uint32_t> canon(m.positions.size());
  for (size_t i = 0; i < m.positions.size(); ++i) {
    std::array<uint32_t, 3> k;
    std::memcpy(k.data(), &m.positions[i], sizeof k);
    canon[i] = ids.try_emplace(k, uint32_t(i)).first->second;
  }
  std::map<std::pair<uint32_t, uint32_t>, int> directed;
  for (size_t t = 0; t < m.triangleCount(); ++t)
    for (int k = 0; k < 3; ++k) directed[{canon[m.indices[3 * t + k]], canon[m.indices[3 * t + (k + 1) % 3]]}]++;
  for (const auto& [e, n] : directed) {
    EXPECT_EQ(n, 1) << what;
    auto rev = directed.find({e.second, e.first});
    EXPECT_TRUE(rev != directed.end() && rev->second == 1) << what << ": open edge";
  }
}

TEST(Mesh, PrimitivesAreClosedAndOutward) {
  TriangleMesh box = makeBox(), sphere = makeSphere(16), cyl = makeCylinder(32, true), knot = makeTorusKnot(2, 3, 0.15f, 128, 12);
  EXPECT_NEAR(test::signedVolume(box), 8.0, 1e-4);
  EXPECT_NEAR(test::signedVolume(sphere), 4.0 / 3.0 * M_PI, 0.1);  // 16 rings: -1.6 % tessellation loss
  EXPECT_NEAR(test::signedVolume(cyl), 2 * M_PI, 0.05);
  EXPECT_GT(test::signedVolume(knot), 0.0);
  expectClosedOriented(box, "box");
  expectClosedOriented(cyl, "cylinder");
  expectClosedOriented(knot, "torus knot");
  TriangleMesh copy = sphere;
  EXPECT_EQ(validateMesh(copy, "sphere"), 0u);
}

TEST(Mesh, TransformMovesPointsAndNormals) {
  TriangleMesh s = makeSphere(8);
  s.transform(Affine::translate({1, 2, 3}) * Affine::scale({2, 2, 2}));
  for (size_t i = 0; i < s.positions.size(); ++i) {
    EXPECT_NEAR(length(s.positions[i] - Vec3(1, 2, 3)), 2.f, 1e-5f);
    EXPECT_NEAR(dot(s.normals[i], normalize(s.positions[i] - Vec3(1, 2, 3))), 1.f, 1e-4f);
  }
}

TEST(Mesh, DegenerateTrianglesAreDropped) {
  TriangleMesh m = makeQuad();
  m.positions.push_back({5, 5, 5});
  m.uvs.push_back({0, 0});
  m.indices.insert(m.indices.end(), {0, 0, 4});
  EXPECT_EQ(validateMesh(m, "quad"), 1u);
  EXPECT_EQ(m.triangleCount(), 2u);
}

TEST(Mesh, AttributeArraysMustMatchThePositions) {
  TriangleMesh m = makeQuad();
  m.normals.assign(3, Vec3(0, 0, 1));
  EXPECT_THROW(validateMesh(m, "quad"), InputError);
  m = makeQuad();
  m.uvs[1] = Vec2(std::nanf(""), 0.f);
  EXPECT_THROW(validateMesh(m, "quad"), InputError);
}

// computeSmoothNormalsAdjoint against central differences of computeSmoothNormals: for a
// pseudo-random dL/dn and direction d, sum_v dL/dp_v . d_v against (L(p + h d) - L(p - h d)) / 2h
// with L = sum_v dL/dn_v . n_v, on a bumpy closed icosphere, an open bent grid (boundary vertices,
// uneven angles) and a bumpy uv sphere welded at its seams and poles. Float rounding of L is
// ~1e-6 of its size, so h = 1e-3 leaves ~1e-3 relative noise; the truncation error is O(h^2).
TEST(Mesh, SmoothNormalsAdjointMatchesFiniteDifferences) {
  uint32_t x = 12345u;
  auto uniform = [&] {
    x = x * 1664525u + 1013904223u;
    return float(x >> 8) / float(1u << 24) * 2.f - 1.f;
  };
  TriangleMesh ico = makeIcosphere(2), grid = makeGrid(5), uv = makeSphere(8);
  for (Vec3& p : ico.positions) p = p * (1.f + 0.15f * uniform());
  for (Vec3& p : grid.positions) p.z = 0.3f * p.x * p.y + 0.1f * uniform();
  // Bumps by position, so that the seam copies stay together.
  for (Vec3& p : uv.positions) p = p * (1.f + 0.1f * std::sin(5.f * p.x + 3.f * p.y) * std::cos(4.f * p.z));
  const EdgeTopology topology = EdgeTopology::build(uv);
  std::vector<uint32_t> weld(uv.positions.size());
  for (uint32_t v = 0; v < weld.size(); ++v) weld[v] = topology.welded(v);
  ASSERT_LT(topology.weldedVertices(), uv.positions.size()) << "the uv sphere has seam copies";
  struct Case {
    const char* what;
    TriangleMesh* mesh;
    const std::vector<uint32_t>* weld;
  };
  for (const Case& c : {Case{"bumpy icosphere", &ico, nullptr}, Case{"bent grid", &grid, nullptr}, Case{"welded uv sphere", &uv, &weld},
                        Case{"uv sphere, unwelded", &uv, nullptr}}) {
    const TriangleMesh& m = *c.mesh;
    const size_t n = m.positions.size();
    std::vector<Vec3> dN(n), dir(n), dP;
    for (size_t v = 0; v < n; ++v) {
      dN[v] = Vec3(uniform(), uniform(), uniform());
      dir[v] = Vec3(uniform(), uniform(), uniform());
    }
    computeSmoothNormalsAdjoint(m, dN, dP, c.weld);
    ASSERT_EQ(dP.size(), n);
    double analytic = 0;
    for (size_t v = 0; v < n; ++v) analytic += double(dot(dP[v], dir[v]));
    auto loss = [&](float h) {
      TriangleMesh moved = m;
      for (size_t v = 0; v < n; ++v) moved.positions[v] = moved.positions[v] + dir[v] * h;
      computeSmoothNormals(moved, c.weld);
      double sum = 0;
      for (size_t v = 0; v < n; ++v) sum += double(dot(dN[v], moved.normals[v]));
      return sum;
    };
    const float h = 1e-3f;
    const double fd = (loss(h) - loss(-h)) / (2.0 * double(h));
    EXPECT_NEAR(analytic, fd, 1e-2 * std::abs(fd)) << c.what;
    EXPECT_GT(std::abs(fd), 1.0) << c.what << ": the direction changes the normals";
  }
  // Welded, the copies share one normal.
  TriangleMesh welded = uv;
  computeSmoothNormals(welded, &weld);
  std::vector<Vec3> first(topology.weldedVertices(), Vec3(0.f));
  std::vector<bool> seen(first.size(), false);
  for (size_t v = 0; v < weld.size(); ++v) {
    if (!seen[weld[v]]) {
      seen[weld[v]] = true;
      first[weld[v]] = welded.normals[v];
    }
    EXPECT_EQ(welded.normals[v], first[weld[v]]) << "copy " << v;
  }
}

}  // namespace
}  // namespace invr

namespace invr {
namespace {

// scene.proto's Plant: the documented counts and extent, valid (no degenerate or non-manifold
// triangles), the same plant for the same seed and another for another seed.
TEST(Mesh, PlantHasItsDocumentedCountsAndExtent) {
  for (auto [leaves, segments] : {std::pair{1, 3}, std::pair{7, 10}, std::pair{100, 18}}) {
    TriangleMesh plant = makePlant(leaves, segments, 7);
    EXPECT_EQ(plant.triangleCount(), plantTriangleCount(leaves, segments));
    EXPECT_EQ(plant.positions.size(), plantVertexCount(leaves, segments));
    EXPECT_EQ(validateMesh(plant, "plant"), 0u) << leaves << " leaves, " << segments << " segments";
    for (const Vec3& p : plant.positions) {
      EXPECT_GE(p.y, -0.01f);
      EXPECT_LE(p.y, 1.05f);
      EXPECT_LE(std::hypot(p.x, p.z), 0.75f);
    }
  }
  EXPECT_EQ(plantTriangleCount(100, 18), 64200u);  // the figure scene.proto quotes
  for (int segments = 3; segments <= 256; ++segments) {  // every leaf_segments a job may ask for
    TriangleMesh leaf = makePlant(1, segments, 11);
    ASSERT_EQ(leaf.triangleCount(), plantTriangleCount(1, segments)) << segments;
    ASSERT_EQ(leaf.positions.size(), plantVertexCount(1, segments)) << segments;
    ASSERT_EQ(validateMesh(leaf, "plant"), 0u) << segments;
  }
  TriangleMesh a = makePlant(20, 12, 3), b = makePlant(20, 12, 3), c = makePlant(20, 12, 4);
  ASSERT_EQ(a.positions.size(), c.positions.size());
  EXPECT_EQ(0, std::memcmp(a.positions.data(), b.positions.data(), a.positions.size() * sizeof(Vec3)));
  EXPECT_NE(0, std::memcmp(a.positions.data(), c.positions.data(), a.positions.size() * sizeof(Vec3)));
}

}  // namespace
}  // namespace invr
