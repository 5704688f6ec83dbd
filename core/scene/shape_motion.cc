#include "core/scene/shape_motion.h"

#include <cmath>

namespace invr {

namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

using M3 = std::array<std::array<double, 3>, 3>;

M3 identity3() { return {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}; }

M3 mul(const M3& a, const M3& b) {
  M3 r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) r[i][j] += a[i][k] * b[k][j];
  return r;
}

// Rotation about one axis by `degrees`, or its derivative per degree.
M3 axisRotation(int axis, double degrees, bool derivative) {
  double r = degrees * kDegree, c = std::cos(r), s = std::sin(r);
  M3 a = derivative ? M3{} : identity3();
  int i = (axis + 1) % 3, j = (axis + 2) % 3;
  if (derivative) {
    a[i][i] = -s * kDegree; a[i][j] = -c * kDegree; a[j][i] = c * kDegree; a[j][j] = -s * kDegree;
  } else {
    a[i][i] = c; a[i][j] = -s; a[j][i] = s; a[j][j] = c;
  }
  return a;
}

// R = Rz Ry Rx (x applied first); with `differentiate` = axis, that axis's factor differentiated.
M3 rotation(Vec3 degrees, int differentiate = -1) {
  M3 r = identity3();
  for (int axis = 0; axis < 3; ++axis) r = mul(axisRotation(axis, degrees[axis], axis == differentiate), r);
  return r;
}

// The affine map p -> L (p - pivot) + offset.
Affine3d aboutPivot(const M3& L, Vec3 pivot, Vec3 offset) {
  Affine3d a;
  for (int i = 0; i < 3; ++i) {
    double o = offset[i];
    for (int j = 0; j < 3; ++j) {
      a.m[i][j] = L[size_t(i)][size_t(j)];
      o -= L[size_t(i)][size_t(j)] * pivot[j];
    }
    a.m[i][3] = o;
  }
  return a;
}

}  // namespace

Affine3d motionMap(const RigidMotion& motion, Vec3 pivot) {
  M3 L = rotation(motion.rotationDegrees);
  for (auto& row : L)
    for (double& v : row) v *= motion.scale;
  return aboutPivot(L, pivot, pivot + motion.translation);
}

Affine3d motionDerivative(const RigidMotion& motion, Vec3 pivot, int component) {
  if (component < 3) {
    Affine3d d = aboutPivot(M3{}, pivot, Vec3(0.f));
    d.m[component][3] = 1.0;
    return d;
  }
  M3 L = component < 6 ? rotation(motion.rotationDegrees, component - 3) : rotation(motion.rotationDegrees);
  if (component < 6)
    for (auto& row : L)
      for (double& v : row) v *= motion.scale;
  return aboutPivot(L, pivot, Vec3(0.f));
}

void ShapeMotion::resize(size_t meshes, size_t groups) {
  meshMotion_.assign(meshes, {});
  appliedMesh_.assign(meshes, {});
  groupMotion_.assign(groups, {});
  appliedGroup_.assign(groups, {});
  velocity_.assign(meshes, {});
  restPositions_.assign(meshes, {});
  restNormals_.assign(meshes, {});
  moving_.assign(meshes, 0);
  deforming_.assign(meshes, 0);
  movingList_.clear();
  appliedMap_.assign(meshes, {});
}

}  // namespace invr
