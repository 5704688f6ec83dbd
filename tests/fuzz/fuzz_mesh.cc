// fuzz_obj / fuzz_ply: parseMesh (the bytes of an uploaded .obj or .ply), then validateMesh as the
// scene builder calls it, then the promises both make (core/geometry/mesh.h). Built twice, with
// INVR_FUZZ_MESH_FORMAT=Obj and =Ply.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/io/mesh_io.h"
#include "tests/fuzz/fuzz_common.h"

#ifndef INVR_FUZZ_MESH_FORMAT
#error "define INVR_FUZZ_MESH_FORMAT as Obj or Ply"
#endif

namespace {

bool finite(const invr::Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finite(const invr::Vec2& v) { return std::isfinite(v.x) && std::isfinite(v.y); }

// parseMesh: whole triangles, every index within the positions (what any consumer of the mesh
// indexes by).
void checkIndices(const invr::TriangleMesh& m) {
  FUZZ_CHECK(m.indices.size() % 3 == 0, std::to_string(m.indices.size()) + " indices");
  for (uint32_t i : m.indices) FUZZ_CHECK(i < m.positions.size(), std::to_string(i) + " of " + std::to_string(m.positions.size()));
}

// validateMesh: besides the indices, every number finite and the attributes per vertex or absent.
// (parseMesh's comment promises finite numbers too, but the OBJ parser leaves positions and uvs
// to validateMesh, which every caller runs; only what validateMesh promises is checked here.)
void checkValidated(const invr::TriangleMesh& m) {
  checkIndices(m);
  for (const auto& p : m.positions) FUZZ_CHECK(finite(p), "position");
  for (const auto& n : m.normals) FUZZ_CHECK(finite(n), "normal");
  for (const auto& t : m.uvs) FUZZ_CHECK(finite(t), "uv");
  FUZZ_CHECK(m.normals.empty() || m.normals.size() == m.positions.size(), std::to_string(m.normals.size()) + " normals");
  FUZZ_CHECK(m.uvs.empty() || m.uvs.size() == m.positions.size(), std::to_string(m.uvs.size()) + " uvs");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  invr::TriangleMesh mesh;
  try {
    mesh = invr::parseMesh(bytes, invr::MeshFormat::INVR_FUZZ_MESH_FORMAT, "fuzz");
  } catch (const invr::InputError& e) {
    invr::fuzz::rejected(e);
    return 0;
  }
  checkIndices(mesh);
  const size_t before = mesh.triangleCount();
  size_t removed = 0;
  try {
    removed = invr::validateMesh(mesh, "fuzz");
  } catch (const invr::InputError& e) {
    invr::fuzz::rejected(e);
    return 0;
  }
  // validateMesh: non-empty, the degenerate triangles gone, positive total area.
  checkValidated(mesh);
  FUZZ_CHECK(removed <= before, std::to_string(removed) + " of " + std::to_string(before) + " removed");
  FUZZ_CHECK(mesh.triangleCount() == before - removed, "triangle count after validation");
  FUZZ_CHECK(mesh.triangleCount() > 0, "an empty mesh passed validation");
  double area = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) area += mesh.triangleArea(t);
  FUZZ_CHECK(!(area <= 0), "zero total area passed validation");
  invr::fuzz::accepted(std::to_string(mesh.positions.size()) + " vertices, " + std::to_string(mesh.triangleCount()) + " triangles");
  return 0;
}
