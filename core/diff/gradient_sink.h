// Sparse gradient accumulation with a deterministic reduction. Each fixed block of work (a tile of
// pixels) owns one TileGradient; paths add entries to a PathGradient that is committed to the tile
// only if every entry is finite (non-finite paths are counted and dropped here, in one place).
// Tiles are then reduced in tile order, so the sum does not depend on thread count or scheduling.
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
  void clear() { entries_.clear(); }
  bool finite() const {
    for (const auto& e : entries_)
      if (!std::isfinite(e.second)) return false;
    return true;
  }
  const std::vector<std::pair<uint32_t, float>>& entries() const { return entries_; }

 private:
  std::vector<std::pair<uint32_t, float>> entries_;
};

class TileGradient {
 public:
  // Appends the path's entries if all are finite; otherwise counts it as non-finite.
  void commit(PathGradient& path) {
    if (path.finite()) entries_.insert(entries_.end(), path.entries().begin(), path.entries().end());
    else ++nonFinite_;
    path.clear();
    if (entries_.size() > (1u << 16)) compact();
  }
  // Sums duplicate indices (in insertion order, so the result is deterministic).
  void compact() {
    std::stable_sort(entries_.begin(), entries_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    merged_.clear();
    for (const auto& e : entries_) {
      if (!merged_.empty() && merged_.back().first == e.first) merged_.back().second += e.second;
      else merged_.emplace_back(e.first, double(e.second));
    }
    // Keep the merged sums as the new entry list (as doubles folded back after the final add).
    carried_.insert(carried_.end(), merged_.begin(), merged_.end());
    entries_.clear();
  }
  // Adds this tile into a dense gradient.
  void reduceInto(std::vector<double>& dense) {
    compact();
    for (const auto& e : carried_) dense[e.first] += e.second;
    carried_.clear();
  }
  uint64_t nonFinite() const { return nonFinite_; }

 private:
  std::vector<std::pair<uint32_t, float>> entries_;
  std::vector<std::pair<uint32_t, double>> merged_, carried_;
  uint64_t nonFinite_ = 0;
};

}  // namespace invr
