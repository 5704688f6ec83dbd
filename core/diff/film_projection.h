// The pinhole camera's film coordinates of a world point and their derivatives, shared by the
// boundary terms (they integrate over curves on the film).
#pragma once

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

}  // namespace invr
