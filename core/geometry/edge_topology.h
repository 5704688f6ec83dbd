// Edges of a triangle mesh after welding vertices that share a position, for the boundary terms of
// shape derivatives (Wang et al. 2023, §5-6): where visibility or shading is discontinuous.
// Meshes carry per-face vertex copies (uv and normal seams, a box's corners, a sphere's poles and
// its phi = 0 seam), so topology is built on welded positions: vertices closer than a tolerance
// relative to the mesh's size are one vertex (±0.0 and rounding at seams included). Otherwise every
// seam would look like a hole, and holes are always silhouettes.
//
// Topology is computed once per mesh; rigid motion keeps coincident vertices coincident, and vertex
// parameters move welded copies together, so it stays valid while shape parameters move the mesh. Which edges are silhouettes depends on the
// viewpoint and is evaluated per point (silhouetteFrom).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/geometry/mesh.h"

namespace invr {

struct MeshEdge {
  static constexpr uint32_t kNone = UINT32_MAX;
  uint32_t v0 = 0, v1 = 0;  // vertex indices (of face0's copies), in face0's winding order
  uint32_t face0 = 0, face1 = kNone;  // kNone: a boundary edge (one face)
  bool nonManifold = false;  // more than two faces meet here (treated like a boundary: always a candidate)
  bool crease = false;       // shading jumps across the edge (face or vertex normals differ)
  bool boundary() const { return face1 == kNone || nonManifold; }
};

class EdgeTopology {
 public:
  // `weldTolerance` is relative to the mesh's bounding-box diagonal.
  static EdgeTopology build(const TriangleMesh& mesh, float weldTolerance = 1e-5f);

  const std::vector<MeshEdge>& edges() const { return edges_; }
  // For a mesh that deforms (vertex parameters): any two faces may turn apart, so every edge with
  // two faces is a crease, whether or not its faces meet at an angle now.
  void markEveryEdgeACrease();
  // For a smooth mesh that deforms: its vertex normals are recomputed over welded vertices
  // (ParameterRegistry), so shading is continuous across every edge with two faces, whatever
  // normals it was loaded with; only silhouettes (per viewpoint) and boundaries remain.
  void markNoEdgeACrease();
  size_t boundaryEdges() const { return boundary_; }
  size_t creaseEdges() const { return creases_; }
  size_t nonManifoldEdges() const { return nonManifold_; }
  size_t weldedVertices() const { return weldedCount_; }
  // Closed (every edge has exactly two faces) and consistently wound (the two faces run along each
  // edge in opposite directions): a surface with an inside, whose outside every face's normal
  // points to, or every face's normal points away from (meshWindingNumber tells which).
  bool closedOriented() const { return closedOriented_; }
  // The welded vertex of each mesh vertex.
  uint32_t welded(uint32_t vertex) const { return weld_[vertex]; }

  // Whether edge e separates, seen from point o, a face turned towards o from one turned away:
  // a silhouette (visibility discontinuity). Boundary edges always are. faceNormals: per triangle,
  // in the mesh's current pose.
  static bool silhouetteFrom(const MeshEdge& e, const TriangleMesh& mesh, const std::vector<Vec3>& faceNormals, Vec3 o);
  // The same for a source at infinity: `towards` is the direction to it (environment lights).
  static bool silhouetteTowards(const MeshEdge& e, const std::vector<Vec3>& faceNormals, Vec3 towards);

 private:
  std::vector<MeshEdge> edges_;
  std::vector<uint32_t> weld_;
  size_t boundary_ = 0, creases_ = 0, nonManifold_ = 0, weldedCount_ = 0;
  bool closedOriented_ = true;
};

}  // namespace invr
