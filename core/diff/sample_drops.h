// Samples the engine drops because a value is not finite, counted in one place. Every stage that
// can meet a non-finite number reports here, and progress shows the total (DESIGN.md: nothing
// non-finite is silently averaged in).
#pragma once

#include <cstdint>

namespace invr {

struct SampleDrops {
  // Camera samples of a primal pass whose radiance was not finite; their pixel is the mean of the
  // samples that remain (a pixel with none left is 0).
  uint64_t primal = 0;
  // Camera samples of a derivative pass whose radiance or any derivative was not finite; dropped
  // from the image and the gradient together, the pixel's other samples reweighted.
  uint64_t derivative = 0;
  // Stage-1 samples of pixel sampling (their cell keeps the statistics of none).
  uint64_t stage1 = 0;
  // Camera samples of a variance pass (Yan et al. 2024) with a non-finite value or derivative.
  uint64_t variance = 0;
  // Pixel-probability map values that were not finite (they get the uniform share only).
  uint64_t pixelMap = 0;
  // Edge samples of a boundary pass (shape parameters) with a non-finite derivative.
  uint64_t boundary = 0;

  uint64_t total() const { return primal + derivative + stage1 + variance + pixelMap + boundary; }
  SampleDrops& operator+=(const SampleDrops& o) {
    primal += o.primal;
    derivative += o.derivative;
    stage1 += o.stage1;
    variance += o.variance;
    pixelMap += o.pixelMap;
    boundary += o.boundary;
    return *this;
  }
};

}  // namespace invr
