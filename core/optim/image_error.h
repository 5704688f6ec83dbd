// Image error of a parameter vector: how far its renders are from the truth's, free of Monte
// Carlo noise as far as possible. Both are rendered with the target renderer and the same random
// numbers (common random numbers), so the difference reflects the parameters, not the sampling.
// Parameter error says how well θ is recovered; image error says how well it reproduces the
// images, which is what a user sees and what a loss alone (noisy, per mini-batch) cannot tell.
#pragma once

#include <vector>

#include "core/job/problem.h"

namespace invr {

inline constexpr StreamId kImageErrorStream{9};  // the image-error meter's renders

class ImageErrorMeter {
 public:
  // Compares the first min(maxViews, views) views at `spp` samples per pixel. With uploaded
  // targets (truth unknown) the targets themselves are the reference.
  ImageErrorMeter(Problem& problem, int maxViews, int spp);

  // Relative RMSE: sqrt(mean over the compared views' pixels and channels of
  // (I(θ) − I*)² / (I*² + 0.01)), the relative L2 loss's weighting, so a light seen directly does
  // not drown out the surfaces and dark regions count. 0.1 means about 10 % per pixel.
  // Writes θ into the problem's scene. `renders`, if given, receives I(θ) per compared view.
  double measure(const std::vector<float>& theta, std::vector<Image>* renders = nullptr);

  const std::vector<Image>& reference() const { return reference_; }
  const std::vector<int>& views() const { return views_; }

 private:
  Problem& problem_;
  std::vector<int> views_;
  RenderOptions options_;
  std::vector<Image> reference_;
  static constexpr double kEpsilon = 0.01;
};

}  // namespace invr
