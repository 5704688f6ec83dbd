#include "core/optim/image_error.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace invr {

ImageErrorMeter::ImageErrorMeter(Problem& p, int maxViews, int spp) : problem_(p) {
  if (maxViews < 1 || spp < 1) throw InputError("image error: views and spp must be positive");
  int n = std::min<int>(maxViews, int(p.scene->cameras.size()));
  for (int v = 0; v < n; ++v) views_.push_back(v);
  // Not the targets' own stream: their noise is not what we compare.
  options_ = transportRenderOptions(p, spp, kImageErrorStream);
  if (!p.groundTruthKnown()) {
    for (int v : views_) reference_.push_back(p.givenTargets.at(size_t(v)));
  } else {
    p.params.write(p.truth, *p.scene);
    for (int v : views_) reference_.push_back(renderView(*p.scene, v, options_).image);
  }
}

double ImageErrorMeter::measure(const std::vector<float>& theta, std::vector<Image>* renders) {
  problem_.params.write(theta, *problem_.scene);
  double sum = 0;
  size_t count = 0;
  if (renders) renders->clear();
  for (size_t i = 0; i < views_.size(); ++i) {
    Image im = renderView(*problem_.scene, views_[i], options_).image;
    const auto& a = im.data();
    const auto& b = reference_[i].data();
    const auto& masks = problem_.gradient.lossMasks;
    const std::vector<float>* mask = size_t(views_[i]) < masks.size() && !masks[size_t(views_[i])].empty() ? &masks[size_t(views_[i])] : nullptr;
    const size_t channels = size_t(im.channels());
    for (size_t k = 0; k < a.size(); ++k) {
      double d = double(a[k]) - double(b[k]);
      double w = mask ? double((*mask)[k / channels]) : 1.0;  // masks have mean 1
      sum += w * d * d / (double(b[k]) * double(b[k]) + kEpsilon);
    }
    count += a.size();
    if (renders) renders->push_back(std::move(im));
  }
  return std::sqrt(sum / double(std::max<size_t>(1, count)));
}

}  // namespace invr
