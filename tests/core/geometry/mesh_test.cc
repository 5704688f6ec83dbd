#include "core/geometry/mesh.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <map>

#include "core/error.h"
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

}  // namespace
}  // namespace invr
