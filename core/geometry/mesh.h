// Triangle meshes: the data, built-in primitives and validation (OBJ/PLY reading: core/io/mesh_io.h).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/math/affine.h"

namespace invr {

struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // per vertex, optional (empty = flat shading)
  std::vector<Vec2> uvs;      // per vertex, optional
  std::vector<uint32_t> indices;  // 3 per triangle
  // Unit geometric normal per triangle (from its winding); filled and kept current by the Scene that
  // holds the mesh (Scene::finalize, vertex updates), empty elsewhere.
  std::vector<Vec3> faceNormals;

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
// Foliage (scene.proto's Plant): `leaves` trifoliate leaves on curved stems from the origin, up +y
// to about 1, within a radius of about 0.7; the same seed gives the same plant. No normals or uvs.
TriangleMesh makePlant(int leaves, int leafSegments, uint64_t seed);
// Its vertex and triangle counts, without building it.
uint64_t plantVertexCount(int leaves, int leafSegments);
uint64_t plantTriangleCount(int leaves, int leafSegments);
// Start meshes of vertex parameters (no seams, no normals, no uvs): an icosahedron subdivided
// `subdivisions` times onto the unit sphere (10 * 4^s + 2 vertices), and a grid of n x n cells
// over [-1, 1]^2 in the xy plane, normal +z.
TriangleMesh makeIcosphere(int subdivisions);
TriangleMesh makeGrid(int cells);
// A relief: makeGrid(cells) with uvs ((x + 1) / 2, (y + 1) / 2), each vertex at z = height(u, v).
TriangleMesh makeHeightfield(int cells, const std::function<float(float u, float v)>& height);

// Throws InputError("<what>: ...") if the mesh is empty, has out-of-range indices, non-finite
// positions, normals or uvs, attribute arrays whose size differs from the positions, an edge
// shared by more than two triangles (non-manifold) or zero total area.
// Degenerate (zero-area) triangles are removed; returns how many were.
size_t validateMesh(TriangleMesh& mesh, const std::string& what);

// The generalised winding number of the mesh about point p: the solid angle its triangles
// subtend, signed by their winding, over 4 pi. For a closed, consistently wound mesh it is 0
// outside, +1 inside if the faces' normals point out and -1 if they point in.
double meshWindingNumber(const TriangleMesh& mesh, Vec3 p);

// Vertex normals for a mesh that has none: each vertex's triangle normals weighted by the
// triangle's angle at the vertex (independent of how finely the surface is tessellated). With
// `weld` (mesh vertex -> welded vertex), copies of a vertex at seams share one normal, summed over
// all their triangles.
void computeSmoothNormals(TriangleMesh& mesh, const std::vector<uint32_t>* weld = nullptr);
// Its adjoint: dL/dpositions (one per vertex, overwritten) from dL/dnormals, dL/d of each unit
// vertex normal that computeSmoothNormals gives at the mesh's positions (with the same weld).
// Smooth meshes under vertex parameters recompute their normals after every update; this takes
// their derivatives back to the vertices.
void computeSmoothNormalsAdjoint(const TriangleMesh& mesh, const std::vector<Vec3>& dNormals, std::vector<Vec3>& dPositions,
                                 const std::vector<uint32_t>* weld = nullptr);

}  // namespace invr
