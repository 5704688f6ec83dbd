// Triangle meshes: built-in primitives, OBJ/PLY loading and validation.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/math/vec.h"

namespace invr {

struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // per vertex, optional (empty = flat shading)
  std::vector<Vec2> uvs;      // per vertex, optional
  std::vector<uint32_t> indices;  // 3 per triangle

  size_t triangleCount() const { return indices.size() / 3; }
  float triangleArea(size_t tri) const;
  void transform(const Affine& xf);
  // Reverses every triangle's winding (so its geometric normal); with `normals` also negates the
  // vertex normals.
  void flipWinding(bool normals);
};

TriangleMesh makeQuad();
TriangleMesh makeBox();
TriangleMesh makeSphere(int rings);
TriangleMesh makeDisk(int segments);  // radius 1 in the xy plane, normal +z
TriangleMesh makeCylinder(int segments, bool capped);
TriangleMesh makeTorusKnot(int p, int q, float tubeRadius, int segments, int tubeSegments);

// Loads .obj (tinyobjloader) or .ply (ascii / binary little- and big-endian).
// Throws InputError naming the file on any problem: malformed or truncated data, indices out of
// range, non-finite numbers; ResourceError when a count the file declares exceeds inputLimits().
// With a budget, the peak memory of reading and parsing (a multiple of the file's size: 8x for
// OBJ, 4x for PLY) is charged before the file is read and released once the mesh is built.
class MemoryBudget;
TriangleMesh loadMesh(const std::filesystem::path& path, MemoryBudget* budget = nullptr);

enum class MeshFormat { Obj, Ply };
// The same from bytes in memory; `name` is what errors call the mesh.
TriangleMesh parseMesh(const std::string& bytes, MeshFormat format, const std::string& name);

// Throws InputError("<what>: ...") if the mesh is empty, has out-of-range indices, non-finite
// positions, normals or uvs, attribute arrays whose size differs from the positions, an edge
// shared by more than two triangles (non-manifold) or zero total area.
// Degenerate (zero-area) triangles are removed; returns how many were.
size_t validateMesh(TriangleMesh& mesh, const std::string& what);

// Vertex normals for a mesh that has none: each vertex's triangle normals weighted by the
// triangle's angle at the vertex (independent of how finely the surface is tessellated).
void computeSmoothNormals(TriangleMesh& mesh);

}  // namespace invr
