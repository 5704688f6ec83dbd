// How far apart two triangle meshes are, as surfaces: the symmetric mean chamfer distance,
//   (mean over a's surface of the distance to b + mean over b's surface of the distance to a) / 2,
// with each mean taken over points spread evenly by area (a fixed stratified set, so the same
// meshes always give the same number) and each distance exact to the nearest triangle among
// those whose centroids are nearest the point (a kd-tree over centroids).
#pragma once

#include <memory>
#include <vector>

#include "core/geometry/mesh.h"

namespace invr {

double symmetricChamferDistance(const TriangleMesh& a, const TriangleMesh& b, int samplesPerMesh = 4096);

// One side kept for repeated measurements against it (the truth of a shape_error): its surface
// points and the tree over its centroids, built once.
class SurfaceDistance {
 public:
  SurfaceDistance(TriangleMesh mesh, int samples = 4096);
  ~SurfaceDistance();
  SurfaceDistance(const SurfaceDistance&) = delete;
  SurfaceDistance& operator=(const SurfaceDistance&) = delete;
  // symmetricChamferDistance(mesh, other, samples), without rebuilding this side.
  double symmetricChamferTo(const TriangleMesh& other) const;

 private:
  struct Index;
  TriangleMesh mesh_;
  int samples_;
  std::vector<Vec3> points_;
  std::unique_ptr<Index> index_;
};

// The length of the diagonal of the mesh's bounding box.
double boundingBoxDiagonal(const TriangleMesh& mesh);

}  // namespace invr
