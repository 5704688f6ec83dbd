#include "core/io/mesh_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <unistd.h>

#include "core/error.h"
#include "core/limits.h"
#include "test_util.h"

namespace invr {
namespace {

std::filesystem::path tmp(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("invr_mesh_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

TEST(MeshIo, LoadsObjAndPly) {
  std::ofstream(tmp("tet.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                   "f 1/1 3/3 2/2\nf 1/1 2/2 4/3\nf 1/1 4/3 3/3\nf 2/2 3/3 4/3\n";
  TriangleMesh obj = loadMesh(tmp("tet.obj"));
  EXPECT_EQ(obj.triangleCount(), 4u);
  EXPECT_EQ(obj.uvs.size(), obj.positions.size());
  EXPECT_NEAR(test::signedVolume(obj), 1.0 / 6.0, 1e-6);

  std::ofstream(tmp("tet.ply")) << "ply\nformat ascii 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\n"
                                   "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
                                   "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  TriangleMesh ply = loadMesh(tmp("tet.ply"));
  EXPECT_EQ(ply.triangleCount(), 4u);
  EXPECT_NEAR(test::signedVolume(ply), 1.0 / 6.0, 1e-6);

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

TEST(MeshIo, BadFilesAreInputErrors) {
  EXPECT_THROW(loadMesh(tmp("missing.obj")), InputError);
  std::ofstream(tmp("mesh.stl")) << "solid";
  EXPECT_THROW(loadMesh(tmp("mesh.stl")), InputError);
  std::ofstream(tmp("bad.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n0\n";
  EXPECT_THROW(loadMesh(tmp("bad.ply")), InputError);
  std::ofstream(tmp("badidx.obj")) << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  EXPECT_THROW({ auto m = loadMesh(tmp("badidx.obj")); validateMesh(m, "badidx"); }, InputError);
}

// The message of the error parsing `bytes` raises ("" if none), and whether it was a limit.
struct ParseOutcome {
  std::string message;
  bool limit = false;
};
ParseOutcome parseError(const std::string& bytes, MeshFormat f) {
  try {
    TriangleMesh m = parseMesh(bytes, f, "m");
    validateMesh(m, "m");
  } catch (const ResourceError& e) {
    return {e.what(), true};
  } catch (const InputError& e) {
    return {e.what(), false};
  }
  return {};
}

bool has(const ParseOutcome& o, const std::string& part) { return o.message.find(part) != std::string::npos; }

TEST(MeshIo, ObjIndicesOfEveryKindAreRangeChecked) {
  auto e = parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//5 2//5 3//5\n", MeshFormat::Obj);
  EXPECT_TRUE(has(e, "references normal 5 of 1")) << e.message;
  e = parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n", MeshFormat::Obj);  // one past the end
  EXPECT_TRUE(has(e, "references normal 2 of 1")) << e.message;
  e = parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/9 3/1\n", MeshFormat::Obj);
  EXPECT_TRUE(has(e, "references texture coordinate 9 of 1")) << e.message;
  e = parseError("v 0 0 0\nv 1 0 0\nf 1 2 7\n", MeshFormat::Obj);
  EXPECT_TRUE(has(e, "references vertex 7 of 2")) << e.message;
  EXPECT_EQ(parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n", MeshFormat::Obj).message, "");
}

TEST(MeshIo, NonFiniteNumbersAreCaughtInEveryFormat) {
  // tinyobjloader turns "nan" and "1e999" into numbers; they must not reach the BVH.
  EXPECT_TRUE(has(parseError("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", MeshFormat::Obj), "is not a finite number"));
  EXPECT_TRUE(has(parseError("v 1e999 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", MeshFormat::Obj), "is not a finite number"));
  EXPECT_TRUE(has(parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 1\nf 1//1 2//1 3//1\n", MeshFormat::Obj), "is not a finite number"));
  EXPECT_TRUE(has(parseError("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt inf 0\nf 1/1 2/1 3/1\n", MeshFormat::Obj), "line 4: 'inf' is not a finite number"));
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  EXPECT_TRUE(has(parseError(head + "nan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MeshFormat::Ply), "not finite"));
  EXPECT_TRUE(has(parseError(head + "1e300 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MeshFormat::Ply), "not finite"));
  EXPECT_TRUE(has(parseError(head + "x 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MeshFormat::Ply), "malformed number 'x' in vertex 0"));
}

TEST(MeshIo, PlyCountsAreCheckedBeforeAnythingIsAllocated) {
  const std::string vertices = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  auto e = parseError(vertices + "element face 4000000000\nproperty list uchar int vertex_indices\nend_header\n", MeshFormat::Ply);
  EXPECT_TRUE(e.limit) << e.message;
  EXPECT_TRUE(has(e, "declares 4000000000 entries (limit 67108864)")) << e.message;
  e = parseError(vertices + "element face -1\nproperty list uchar int vertex_indices\nend_header\n", MeshFormat::Ply);
  EXPECT_FALSE(e.limit);
  EXPECT_TRUE(has(e, "count '-1' is not a non-negative integer")) << e.message;
  // In bounds, but more entries than the file has bytes for: an error before any reservation.
  e = parseError(vertices + "element face 1000000\nproperty list uchar int vertex_indices\nend_header\n" + std::string(36, '\0'),
                 MeshFormat::Ply);
  EXPECT_TRUE(has(e, "declares 1000000 entries, but the file holds at most")) << e.message;
  // A face list longer than any polygon we accept (uint32 count of 4e9).
  std::string bad = vertices + "element face 1\nproperty list uint int vertex_indices\nend_header\n" + std::string(36, '\0');
  uint32_t n = 4000000000u;
  bad.append(reinterpret_cast<const char*>(&n), 4);
  bad.append(16, '\0');
  e = parseError(bad, MeshFormat::Ply);
  EXPECT_TRUE(has(e, "list length is 4000000000")) << e.message;
}

TEST(MeshIo, PlyIndicesWrongCountsAndTruncationAreNamed) {
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_TRUE(has(parseError(head + "3 0 1 3\n", MeshFormat::Ply), "face 0: vertex index is 3"));
  EXPECT_TRUE(has(parseError(head + "3 0 1 -1\n", MeshFormat::Ply), "face 0: vertex index is -1"));
  EXPECT_TRUE(has(parseError(head + "3 0 1 1.5\n", MeshFormat::Ply), "vertex index is 1.5"));
  EXPECT_TRUE(has(parseError(head + "3 0 1\n", MeshFormat::Ply), "truncated data in face 0"));
  EXPECT_TRUE(has(parseError(head + "2 0 1\n", MeshFormat::Ply), "fewer than 3 vertices"));
  EXPECT_TRUE(has(parseError("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n", MeshFormat::Ply), "no end_header"));
  EXPECT_TRUE(has(parseError("ply\nformat ascii 1.0\nelement vertex 3\nproperty quaternion x\nend_header\n", MeshFormat::Ply),
                  "unknown property type 'quaternion'"));
  EXPECT_TRUE(has(parseError("ply\nelement vertex 0\nend_header\n", MeshFormat::Ply), "no 'format' line"));
  EXPECT_EQ(parseError(head + "3 0 1 2\n", MeshFormat::Ply).message, "");
  // Found by fuzz_ply: faces whose indices have no vertices to refer to.
  EXPECT_TRUE(has(parseError("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 0 0\n",
                             MeshFormat::Ply),
                  "faces but no vertices"));
}

// Binary PLYs in both byte orders, with and without normals and uvs, give the same mesh.
TEST(MeshIo, PlyBinaryBothEndiansWithAndWithoutAttributes) {
  auto put = [](std::string& out, const void* p, size_t n, bool big) {
    std::string b(static_cast<const char*>(p), n);
    if (big) std::reverse(b.begin(), b.end());
    out += b;
  };
  for (bool big : {false, true})
    for (bool attrs : {false, true}) {
      std::string f = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                      " 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
      if (attrs) f += "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n";
      f += "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
      const float v[3][8] = {{0, 0, 0, 0, 0, 2, 0, 0}, {1, 0, 0, 0, 0, 2, 1, 0}, {0, 1, 0, 0, 0, 2, 0, 1}};
      for (const auto& vert : v)
        for (int k = 0; k < (attrs ? 8 : 3); ++k) put(f, &vert[k], 4, big);
      f += char(3);
      for (int32_t i : {0, 1, 2}) put(f, &i, 4, big);
      TriangleMesh m = parseMesh(f, MeshFormat::Ply, "m");
      ASSERT_EQ(m.triangleCount(), 1u);
      EXPECT_EQ(m.positions[1].x, 1.f);
      EXPECT_EQ(m.positions[2].y, 1.f);
      EXPECT_EQ(m.normals.size(), attrs ? 3u : 0u);
      EXPECT_EQ(m.uvs.size(), attrs ? 3u : 0u);
      if (attrs) {
        EXPECT_EQ(m.normals[0].z, 1.f);  // normalised
        EXPECT_EQ(m.uvs[2].y, 1.f);
      }
    }
}

// ASCII with normals and uvs (and quads, split in two); binary files cut short or holding NaN.
TEST(MeshIo, PlyAsciiWithAttributesAndBadBinaryData) {
  TriangleMesh m = parseMesh("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                             "property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n"
                             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                             "0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n0 1 0 0 0 1 0 1\n4 0 1 2 3\n",
                             MeshFormat::Ply, "quad");
  EXPECT_EQ(m.triangleCount(), 2u);
  ASSERT_EQ(m.normals.size(), 4u);
  ASSERT_EQ(m.uvs.size(), 4u);
  EXPECT_EQ(m.uvs[2].x, 1.f);
  EXPECT_EQ(m.uvs[3].y, 1.f);
  const std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string body;
  const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  body.append(reinterpret_cast<const char*>(v), sizeof v);
  body += char(3);
  const int32_t idx[3] = {0, 1, 2};
  body.append(reinterpret_cast<const char*>(idx), sizeof idx);
  EXPECT_EQ(parseError(head + body, MeshFormat::Ply).message, "");
  auto e = parseError(head + body.substr(0, body.size() - 5), MeshFormat::Ply);
  EXPECT_TRUE(has(e, "truncated")) << e.message;
  std::string nan = body;
  const float q = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan[4], &q, 4);
  e = parseError(head + nan, MeshFormat::Ply);
  EXPECT_TRUE(has(e, "not finite")) << e.message;
  std::string far = body;
  const int32_t bad = 7;
  std::memcpy(&far[far.size() - 4], &bad, 4);
  e = parseError(head + far, MeshFormat::Ply);
  EXPECT_TRUE(has(e, "vertex index is 7")) << e.message;
}

TEST(MeshIo, PlyElementsMustFitTheFileTogether) {
  // Elements without properties would be read from no bytes at all, however many they declare.
  auto e = parseError("ply\nformat ascii 1.0\nelement foo 67108864\nend_header\n", MeshFormat::Ply);
  EXPECT_TRUE(has(e, "element 'foo' has entries but no properties")) << e.message;
  // Each element alone fits in what follows the header; both together do not.
  std::string two = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element extra 3\nproperty double w\nend_header\n" + std::string(36, '\0');
  e = parseError(two, MeshFormat::Ply);
  EXPECT_TRUE(has(e, "element 'extra' declares 3 entries, but the file holds at most 0")) << e.message;
  // Vertex elements together within the vertex limit.
  std::string many = "ply\nformat ascii 1.0\n";
  for (int k = 0; k < 3; ++k) many += "element vertex 30000000\nproperty uchar x\n";
  e = parseError(many + "end_header\n" + std::string(200000000, '0'), MeshFormat::Ply);
  EXPECT_TRUE(e.limit) << e.message;
  EXPECT_TRUE(has(e, "90000000 vertices (limit 67108864)")) << e.message;
}

TEST(MeshIo, ObjLinesEndingInCarriageReturnsAreCheckedToo) {
  // tinyobjloader ends a line at a lone '\r' as well.
  EXPECT_TRUE(has(parseError("o x\rv nan 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r", MeshFormat::Obj), "line 2: 'nan' is not a finite number"));
}

TEST(MeshIo, ReadingAMeshIsChargedToTheBudgetBeforeTheFileIsRead) {
  std::ofstream(tmp("budget.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  MemoryBudget tight(100);  // the file is 32 bytes; reading and parsing an OBJ is charged 8x that
  EXPECT_THROW(loadMesh(tmp("budget.obj"), &tight), ResourceError);
  EXPECT_EQ(tight.used(), 0u);
  MemoryBudget roomy(1000);
  TriangleMesh m = loadMesh(tmp("budget.obj"), &roomy);
  EXPECT_EQ(m.triangleCount(), 1u);
  EXPECT_EQ(roomy.used(), 0u);  // the working set is given back; the caller charges what it keeps
}

}  // namespace
}  // namespace invr
