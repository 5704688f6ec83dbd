// Affine maps of 3-space, the one type for them: a 3x4 matrix, row-major, the last row (0 0 0 1)
// implied. In float for mesh transforms (Affine), in double for shape motion, its derivatives
// (which are not motions: no unit last row is assumed of them) and Mitsuba's matrices (Affine3d).
// Points and vectors are computed in T and returned as float Vec3.
#pragma once

#include <cmath>

#include "core/math/vec.h"

namespace invr {

template <class T>
struct AffineMap {
  T m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};

  Vec3 point(Vec3 p) const {
    return {float(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3]), float(m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3]),
            float(m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3])};
  }
  Vec3 vector(Vec3 v) const {
    return {float(m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z), float(m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z),
            float(m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z)};
  }
  // The transpose of the linear part applied to v.
  Vec3 transposedVector(Vec3 v) const {
    return {float(m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z), float(m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z),
            float(m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z)};
  }
  // Composition: (a * b).point(p) == a.point(b.point(p)).
  friend AffineMap operator*(const AffineMap& a, const AffineMap& b) {
    AffineMap r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) {
        T s = j == 3 ? a.m[i][3] : T(0);
        for (int k = 0; k < 3; ++k) s += a.m[i][k] * b.m[k][j];
        r.m[i][j] = s;
      }
    return r;
  }
  // Of an invertible map (cofactors over the determinant).
  AffineMap inverse() const {
    const auto& a = m;
    const T c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1], c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2], c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    const T inv = T(1) / (a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02);
    AffineMap r;
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
  AffineMap linearPart() const {  // the same map without its translation
    AffineMap r = *this;
    for (auto& row : r.m) row[3] = T(0);
    return r;
  }
  bool isIdentity() const {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j)
        if (m[i][j] != (i == j ? T(1) : T(0))) return false;
    return true;
  }
  static AffineMap zero() {
    AffineMap r;
    for (auto& row : r.m)
      for (T& v : row) v = T(0);
    return r;
  }
  static AffineMap scale(Vec3 s) {
    AffineMap a;
    a.m[0][0] = s.x;
    a.m[1][1] = s.y;
    a.m[2][2] = s.z;
    return a;
  }
  static AffineMap translate(Vec3 t) {
    AffineMap a;
    a.m[0][3] = t.x;
    a.m[1][3] = t.y;
    a.m[2][3] = t.z;
    return a;
  }
  // About coordinate axis `axis` (0: x, 1: y, 2: z), right-handed.
  static AffineMap rotate(int axis, float degrees) {
    const float r = degrees * kPi / 180.f, c = std::cos(r), s = std::sin(r);
    AffineMap a;
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    a.m[i][i] = c;
    a.m[i][j] = -s;
    a.m[j][i] = s;
    a.m[j][j] = c;
    return a;
  }
};

using Affine = AffineMap<float>;
using Affine3d = AffineMap<double>;

}  // namespace invr
