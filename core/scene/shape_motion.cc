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

Vec3 Affine3d::point(Vec3 p) const {
  return Vec3(float(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3]), float(m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3]),
              float(m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]));
}

Vec3 Affine3d::vector(Vec3 v) const {
  return Vec3(float(m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z), float(m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z),
              float(m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z));
}

Vec3 Affine3d::transposedVector(Vec3 v) const {
  return Vec3(float(m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z), float(m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z),
              float(m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z));
}

Affine3d operator*(const Affine3d& a, const Affine3d& b) {
  Affine3d r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) {
      double s = j == 3 ? a.m[i][3] : 0.0;
      for (int k = 0; k < 3; ++k) s += a.m[i][k] * b.m[k][j];
      r.m[i][j] = s;
    }
  return r;
}

Affine3d Affine3d::inverse() const {
  const auto& a = m;
  double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1], c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2], c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
  double det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
  double inv = 1.0 / det;
  Affine3d r;
  r.m[0][0] = c00 * inv;
  r.m[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) * inv;
  r.m[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) * inv;
  r.m[1][0] = c01 * inv;
  r.m[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) * inv;
  r.m[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) * inv;
  r.m[2][0] = c02 * inv;
  r.m[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) * inv;
  r.m[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) * inv;
  for (int i = 0; i < 3; ++i) r.m[i][3] = -(r.m[i][0] * a[0][3] + r.m[i][1] * a[1][3] + r.m[i][2] * a[2][3]);
  return r;
}

Affine3d Affine3d::linearPart() const {
  Affine3d r = *this;
  for (auto& row : r.m) row[3] = 0.0;
  return r;
}

Affine3d Affine3d::zero() {
  Affine3d r;
  for (auto& row : r.m)
    for (double& v : row) v = 0.0;
  return r;
}

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
  movingList_.clear();
  appliedMap_.assign(meshes, {});
}

}  // namespace invr
