// A resampling reservoir (Wang et al. 2023, Alg. 1) holding one light sample in re-placeable form.
#pragma once

#include "core/lights/light.h"

namespace invr {

struct Reservoir {
  LightSampleRef y;
  double wSum = 0.0;   // sum of resampling weights
  float M = 0.f;       // candidates represented (confidence)
  float W = 0.f;       // unbiased contribution weight of y (0: empty, or target 0)
  float targetY = 0.f; // target function at y for the owning shading point

  // Streams candidate x with weight w: keeps it with probability w / wSum. Returns true if kept.
  // Does not touch M (callers count candidates, which differ for fresh and reused inputs).
  bool stream(const LightSampleRef& x, double w, float target, float u) {
    if (!(w > 0.0)) return false;
    wSum += w;
    if (double(u) * wSum < w) {
      y = x;
      targetY = target;
      return true;
    }
    return false;
  }
  // One fresh candidate (Alg. 1, UpdateReservoir).
  bool update(const LightSampleRef& x, double w, float target, float u) {
    M += 1.f;
    return stream(x, w, target, u);
  }
  // W = wSum / (target(y) * normalisation); zero whenever the target at y is zero.
  void finalize(float normalisation) {
    W = (targetY > 0.f && normalisation > 0.f && wSum > 0.0) ? float(wSum / (double(targetY) * normalisation)) : 0.f;
  }
};

}  // namespace invr
