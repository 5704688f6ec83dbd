#include "core/math/sampling.h"

#include "core/error.h"

#include <algorithm>

namespace invr {

Distribution1D::Distribution1D(std::span<const float> weights) : pmf_(weights.size()), cdf_(weights.size() + 1) {
  cdf_[0] = 0;
  for (size_t i = 0; i < weights.size(); ++i) cdf_[i + 1] = cdf_[i] + std::max(0.f, weights[i]);
  total_ = cdf_.back();
  if (total_ <= 0) {
    // All-zero weights: fall back to uniform so sampling is still defined.
    for (size_t i = 0; i <= weights.size(); ++i) cdf_[i] = double(i);
    total_ = 0;
  }
  double norm = cdf_.back();
  invPmf_.resize(weights.size());
  for (size_t i = 0; i < weights.size(); ++i) {
    double p = (cdf_[i + 1] - cdf_[i]) / norm;
    pmf_[i] = float(p);
    invPmf_[i] = p > 0 ? float(1.0 / p) : 0.f;
    cdf_[i] /= norm;
  }
  cdf_.back() = 1.0;
  if (pmf_.size() > 8) {  // guide[k]: the cell that holds k / n
    const size_t n = pmf_.size();
    guide_.resize(n);
    size_t i = 0;
    for (size_t k = 0; k < n; ++k) {
      const double x = double(k) / double(n);
      while (i + 1 < n && cdf_[i + 1] <= x) ++i;
      guide_[k] = uint32_t(i);
    }
  }
}

size_t Distribution1D::sample(float u, float* remapped) const {
  // First cell whose upper cdf bound exceeds u; skips zero-probability cells. A linear scan beats
  // binary search for the few-entry distributions that light selection mostly sees.
  size_t i;
  if (pmf_.size() == 1) {  // one light, one-triangle emitter: nothing to choose
    if (remapped) *remapped = u;
    return 0;
  }
  if (pmf_.size() <= 8) {
    // Counting the bounds at or below u, without branches: u is random, so a scan's exit branch
    // mispredicts about once per call.
    i = 0;
    for (size_t j = 1; j < pmf_.size(); ++j) i += size_t(cdf_[j] <= double(u));
  } else {
    // Guide table (the cutpoint method): start from the cell holding the lower end of u's bucket
    // and step to the cell with cdf[i] <= u < cdf[i + 1]. The same cell as a binary search, in
    // O(1) expected steps; environment maps made the binary search a quarter of a backlit step.
    const double du = double(u), g = du * double(guide_.size());
    i = guide_[g > 0.0 ? std::min(guide_.size() - 1, size_t(g)) : 0];
    while (i > 0 && cdf_[i] > du) --i;  // k / n may round above u
    while (i + 1 < pmf_.size() && cdf_[i + 1] <= du) ++i;
  }
  while (pmf_[i] == 0.f && i > 0) --i;  // guards u landing exactly on a boundary
  INVR_INVARIANT(i < pmf_.size() && (pmf_[i] > 0.f || total_ == 0.0), "Distribution1D::sample left the distribution or chose a cell of probability 0");
  if (remapped) *remapped = std::clamp(float(double(u) - cdf_[i]) * invPmf_[i], 0.f, 0x1.fffffep-1f);
  return i;
}

Distribution2D::Distribution2D(std::span<const float> weights, int width, int height) : w_(width), h_(height) {
  std::vector<float> rowSums(height);
  rows_.reserve(height);
  for (int y = 0; y < height; ++y) {
    rows_.emplace_back(weights.subspan(size_t(y) * width, width));
    rowSums[y] = float(rows_.back().total());
  }
  marginal_ = Distribution1D(rowSums);
}

Vec2 Distribution2D::sample(Vec2 u, float* pdf) const {
  float ry, rx;
  size_t y = marginal_.sample(u.y, &ry);
  size_t x = rows_[y].sample(u.x, &rx);
  if (pdf) *pdf = marginal_.pmf(y) * rows_[y].pmf(x) * float(w_) * float(h_);
  return {(float(x) + rx) / float(w_), (float(y) + ry) / float(h_)};
}

float Distribution2D::pdf(Vec2 p) const {
  int x = std::clamp(int(p.x * float(w_)), 0, w_ - 1);
  int y = std::clamp(int(p.y * float(h_)), 0, h_ - 1);
  return marginal_.pmf(y) * rows_[y].pmf(x) * float(w_) * float(h_);
}

}  // namespace invr
