// Sparse gradient accumulation with a deterministic reduction. Each fixed block of work (a tile of
// pixels) owns one TileGradient; the samples of a pixel add entries to a PathGradient, which the
// pass driver checks (non-finite samples are dropped and counted there) and commits through the
// working thread's GradientScratch. Tiles are then reduced in tile order, so the sum does not
// depend on thread count or scheduling.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace invr {

class PathGradient {
 public:
  void add(uint32_t index, float value) { entries_.emplace_back(index, value); }
  void clear() {
    entries_.clear();
    pixel_ = kNoPixel;
  }
  // The film pixel whose dL/dI weighs this sample (boundary terms set it where they read the
  // adjoint; a camera sample's pixel is the pass driver's): where a derivative image puts it.
  static constexpr uint64_t kNoPixel = UINT64_MAX;
  void setPixel(uint64_t pixel) { pixel_ = pixel; }
  uint64_t pixel() const { return pixel_; }
  // The sum of the entries of one parameter value.
  double sumOf(uint32_t index) const {
    double s = 0;
    for (const auto& e : entries_)
      if (e.first == index) s += double(e.second);
    return s;
  }
  size_t size() const { return entries_.size(); }
  void truncate(size_t n) { entries_.resize(std::min(n, entries_.size())); }
  // Whether the entries from index `from` on are all finite.
  bool finiteFrom(size_t from) const {
    for (size_t i = from; i < entries_.size(); ++i)
      if (!std::isfinite(entries_[i].second)) return false;
    return true;
  }
  const std::vector<std::pair<uint32_t, float>>& entries() const { return entries_; }

 private:
  std::vector<std::pair<uint32_t, float>> entries_;
  uint64_t pixel_ = kNoPixel;
};

// A derivative image: d(mean of I's channels)/d theta_index per film pixel, for one parameter value
// (GradientRequest::derivativeImage). The passes add each sample's entries of that value to the
// pixel it belongs to, per tile or chunk, reduced in order (the same image for any thread count).
struct PixelDerivativeSink {
  uint32_t index = 0;         // the parameter value (ParameterRegistry order)
  std::vector<double> image;  // width * height, row-major
};

// One tile's summed derivatives: (parameter index, sum) for each index its paths touched.
class TileGradient {
 public:
  // Adds this tile into a dense gradient.
  void reduceInto(std::vector<double>& dense) const {
    for (const auto& e : sums_) dense[e.first] += e.second;
  }

 private:
  friend class GradientScratch;
  std::vector<std::pair<uint32_t, double>> sums_;
};

// A thread's dense accumulator for the tile it is working on: paths add into one double per
// parameter (in the order they are committed, so each index's sum is the same for any thread
// count), and flush() hands the touched sums to the tile. Dense rather than sorting a list of
// entries per tile: a tile's paths touch few indices many times (bilinear texels).
class GradientScratch {
 public:
  explicit GradientScratch(size_t parameters = 0) : sum_(parameters, 0.0), touched_(parameters, 0) {}
  size_t parameters() const { return sum_.size(); }
  // Adds scale * the path's entries (the caller checked they are finite) and clears the path.
  void commit(PathGradient& path, float scale = 1.f) {
    for (const auto& e : path.entries()) {
      if (!touched_[e.first]) {
        touched_[e.first] = 1;
        order_.push_back(e.first);
      }
      sum_[e.first] += double(e.second) * double(scale);
    }
    path.clear();
  }
  // Moves what was committed since the last flush into `tile` and clears this scratch.
  void flush(TileGradient& tile) {
    tile.sums_.reserve(tile.sums_.size() + order_.size());
    for (uint32_t i : order_) {
      tile.sums_.emplace_back(i, sum_[i]);
      sum_[i] = 0.0;
      touched_[i] = 0;
    }
    order_.clear();
  }

 private:
  std::vector<double> sum_;
  std::vector<uint8_t> touched_;
  std::vector<uint32_t> order_;  // indices in first-touch order
};

}  // namespace invr
