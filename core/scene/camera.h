// Pinhole camera from a look-at frame. Pixel (0,0) is the top-left corner of the image.
#pragma once

#include <string>

#include "core/math/vec.h"

namespace invr {

struct Camera {
  std::string name;
  Vec3 eye{0, 0, 5}, forward{0, 0, -1}, right{1, 0, 0}, up{0, 1, 0};
  float tanHalfFovY = 0.364f;

  static Camera lookAt(Vec3 eye, Vec3 target, Vec3 upHint, float fovYDegrees) {
    Camera c;
    c.eye = eye;
    c.forward = normalize(target - eye);
    c.right = normalize(cross(c.forward, upHint));
    c.up = cross(c.right, c.forward);
    c.tanHalfFovY = std::tan(0.5f * fovYDegrees * kPi / 180.f);
    return c;
  }
  // Direction through film position (px, py) in pixels, for a width x height film.
  Vec3 direction(float px, float py, int width, int height) const {
    float sy = tanHalfFovY * (1.f - 2.f * py / float(height));
    float sx = tanHalfFovY * (2.f * px - float(width)) / float(height);  // aspect folded in
    return normalize(forward + right * sx + up * sy);
  }
  // The film position (px, py) a point projects to: the inverse of direction(). False if the
  // point is behind the camera or outside the film.
  bool project(Vec3 p, int width, int height, float& px, float& py) const {
    Vec3 d = p - eye;
    float z = dot(d, forward);
    if (!(z > 0.f)) return false;
    float sx = dot(d, right) / z, sy = dot(d, up) / z;
    px = 0.5f * (sx * float(height) / tanHalfFovY + float(width));
    py = 0.5f * float(height) * (1.f - sy / tanHalfFovY);
    return px >= 0.f && py >= 0.f && px < float(width) && py < float(height);
  }
};

}  // namespace invr
