// The pinhole camera's film coordinates of a world point and their derivatives, shared by the
// boundary terms (they integrate over curves on the film).
#pragma once

#include <cmath>

#include "core/scene/camera.h"

namespace invr {

// Film position (pixels) of p, for a point in front of the camera (no film bounds check).
inline Vec2 filmPosition(const Camera& cam, Vec3 p, int width, int height) {
  Vec3 d = p - cam.eye;
  float z = dot(d, cam.forward);
  float sx = dot(d, cam.right) / z, sy = dot(d, cam.up) / z;
  return Vec2(0.5f * (sx * float(height) / cam.tanHalfFovY + float(width)), 0.5f * float(height) * (1.f - sy / cam.tanHalfFovY));
}

// d(film x)/dp and d(film y)/dp at p.
inline void filmJacobian(const Camera& cam, Vec3 p, int height, Vec3& dx, Vec3& dy) {
  Vec3 d = p - cam.eye;
  float z = dot(d, cam.forward);
  float k = 0.5f * float(height) / cam.tanHalfFovY;
  dx = (cam.right - cam.forward * (dot(d, cam.right) / z)) * (k / z);
  dy = (cam.up - cam.forward * (dot(d, cam.up) / z)) * (-k / z);
}

// A film position in double precision: where the primary term's two side samples straddle an edge
// a few float roundings of its point away, float film coordinates (an ulp of 7.6e-6 px at x = 64)
// are too coarse to say which side of the edge a sample lies on.
struct FilmPoint {
  double x = 0, y = 0;
};

// filmPosition in double precision (p itself, a float point, is taken as exact).
inline FilmPoint filmPositionPrecise(const Camera& cam, Vec3 p, int width, int height) {
  const double d[3] = {double(p.x) - double(cam.eye.x), double(p.y) - double(cam.eye.y), double(p.z) - double(cam.eye.z)};
  auto dot3 = [&](Vec3 a) { return d[0] * double(a.x) + d[1] * double(a.y) + d[2] * double(a.z); };
  const double z = dot3(cam.forward), sx = dot3(cam.right) / z, sy = dot3(cam.up) / z;
  return {0.5 * (sx * double(height) / double(cam.tanHalfFovY) + double(width)), 0.5 * double(height) * (1.0 - sy / double(cam.tanHalfFovY))};
}

// Camera::direction in double precision, rounded to float at the end.
inline Vec3 filmDirectionPrecise(const Camera& cam, double px, double py, int width, int height) {
  const double t = double(cam.tanHalfFovY), sy = t * (1.0 - 2.0 * py / double(height)), sx = t * (2.0 * px - double(width)) / double(height);
  const double d[3] = {double(cam.forward.x) + double(cam.right.x) * sx + double(cam.up.x) * sy,
                       double(cam.forward.y) + double(cam.right.y) * sx + double(cam.up.y) * sy,
                       double(cam.forward.z) + double(cam.right.z) * sx + double(cam.up.z) * sy};
  const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  return Vec3(float(d[0] / len), float(d[1] / len), float(d[2] / len));
}

}  // namespace invr
