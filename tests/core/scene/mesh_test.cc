#include "core/scene/mesh.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <array>
#include <cstring>
#include <unistd.h>

#include "core/error.h"

namespace invr {
namespace {

std::filesystem::path tmp(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("invr_mesh_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

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

// Outward orientation: the signed volume (divergence theorem) is positive.
double signedVolume(const TriangleMesh& m) {
  double v = 0;
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    Vec3 a = m.positions[m.indices[3 * t]], b = m.positions[m.indices[3 * t + 1]], c = m.positions[m.indices[3 * t + 2]];
    v += dot(a, cross(b, c)) / 6.0;
  }
  return v;
}

TEST(Mesh, PrimitivesAreClosedAndOutward) {
  TriangleMesh box = makeBox(), sphere = makeSphere(16), cyl = makeCylinder(32, true), knot = makeTorusKnot(2, 3, 0.15f, 128, 12);
  EXPECT_NEAR(signedVolume(box), 8.0, 1e-4);
  EXPECT_NEAR(signedVolume(sphere), 4.0 / 3.0 * M_PI, 0.1);  // 16 rings: -1.6 % tessellation loss
  EXPECT_NEAR(signedVolume(cyl), 2 * M_PI, 0.05);
  EXPECT_GT(signedVolume(knot), 0.0);
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

TEST(Mesh, LoadsObjAndPly) {
  std::ofstream(tmp("tet.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                   "f 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/3\nf 2/2 3/3 4/3\n";
  TriangleMesh obj = loadMesh(tmp("tet.obj"));
  EXPECT_EQ(obj.triangleCount(), 4u);
  EXPECT_EQ(obj.uvs.size(), obj.positions.size());
  EXPECT_NEAR(signedVolume(obj), 1.0 / 6.0, 1e-6);

  std::ofstream(tmp("tet.ply")) << "ply\nformat ascii 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\n"
                                   "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
                                   "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  TriangleMesh ply = loadMesh(tmp("tet.ply"));
  EXPECT_EQ(ply.triangleCount(), 4u);
  EXPECT_NEAR(signedVolume(ply), 1.0 / 6.0, 1e-6);

  // Binary little-endian with a quad face (triangulated) and an extra element to skip.
  {
    std::ofstream f(tmp("quad.ply"), std::ios::binary);
    f << "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 1\nproperty list uchar uint vertex_indices\nelement extra 1\nproperty double w\nend_header\n";
    float v[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    f.write(reinterpret_cast<char*>(v), sizeof v);
    unsigned char n = 4;
    uint32_t idx[4] = {0, 1, 2, 3};
    f.write(reinterpret_cast<char*>(&n), 1);
    f.write(reinterpret_cast<char*>(idx), sizeof idx);
    double w = 1.0;
    f.write(reinterpret_cast<char*>(&w), sizeof w);
  }
  TriangleMesh quad = loadMesh(tmp("quad.ply"));
  EXPECT_EQ(quad.triangleCount(), 2u);
  EXPECT_NEAR(quad.triangleArea(0) + quad.triangleArea(1), 1.f, 1e-6f);
}

TEST(Mesh, BadFilesAreInputErrors) {
  EXPECT_THROW(loadMesh(tmp("missing.obj")), InputError);
  std::ofstream(tmp("mesh.stl")) << "solid";
  EXPECT_THROW(loadMesh(tmp("mesh.stl")), InputError);
  std::ofstream(tmp("bad.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n0\n";
  EXPECT_THROW(loadMesh(tmp("bad.ply")), InputError);
  std::ofstream(tmp("badidx.obj")) << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  EXPECT_THROW({ auto m = loadMesh(tmp("badidx.obj")); validateMesh(m, "badidx"); }, InputError);
}

TEST(Mesh, DegenerateTrianglesAreDropped) {
  TriangleMesh m = makeQuad();
  m.positions.push_back({5, 5, 5});
  m.indices.insert(m.indices.end(), {0, 0, 4});
  EXPECT_EQ(validateMesh(m, "quad"), 1u);
  EXPECT_EQ(m.triangleCount(), 2u);
}

}  // namespace
}  // namespace invr
