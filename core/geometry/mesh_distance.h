// How far apart two triangle meshes are, as surfaces: the symmetric mean chamfer distance,
//   (mean over a's surface of the distance to b + mean over b's surface of the distance to a) / 2,
// with each mean taken over points spread evenly by area (a fixed stratified set, so the same
// meshes always give the same number) and each distance exact to the nearest triangle among
// those whose centroids are nearest the point (a kd-tree over centroids).
#pragma once

#include "core/geometry/mesh.h"

namespace invr {

double symmetricChamferDistance(const TriangleMesh& a, const TriangleMesh& b, int samplesPerMesh = 8192);

// The length of the diagonal of the mesh's bounding box.
double boundingBoxDiagonal(const TriangleMesh& mesh);

}  // namespace invr
