// Reservoirs from the previous gradient step, anchored on surfaces (Wang et al. 2023, §4.2):
// each keeps its shading point as (triangle, barycentrics) so it follows the geometry when
// parameters change, and a kd-tree over the current shading points finds reuse candidates.
#pragma once

#include <memory>
#include <vector>

#include "core/restir/reservoir.h"
#include "core/scene/scene.h"

namespace invr {

struct StoredReservoir {
  Reservoir r;
  uint32_t mesh = 0, tri = 0;
  float b1 = 0.f, b2 = 0.f;
  Vec3 woWorld;    // towards the camera that created it (its BSDF target depends on it)
  uint32_t view = 0;
  // Derived from the anchor by refresh():
  Vec3 p, n;
};

class ReservoirStore {
 public:
  ReservoirStore();
  ~ReservoirStore();
  ReservoirStore(ReservoirStore&&) noexcept;
  ReservoirStore& operator=(ReservoirStore&&) noexcept;

  const std::vector<StoredReservoir>& items() const { return items_; }
  size_t size() const { return items_.size(); }
  // New contents whose p and n must be (re)computed from their anchors by the next refresh().
  void assign(std::vector<StoredReservoir> items);
  // New contents whose p and n are already placed in geometry version `geometryVersion`.
  void assignPlaced(std::vector<StoredReservoir> items, uint64_t geometryVersion);

  // Re-places every shading point on the current geometry if it moved since the points were
  // placed (light samples are re-placed lazily, on use), and rebuilds the kd-tree. Call before
  // neighbours() whenever items or the scene changed.
  void refresh(const Scene& scene);

  // Up to k nearest reservoirs within `radius` of p whose normal n' has dot(n, n') >= normalDot.
  // Returns how many indices were written to out (which must hold k entries).
  int neighbours(Vec3 p, Vec3 n, int k, float radius, float normalDot, uint32_t* out) const;
  bool empty() const { return items_.empty(); }

 private:
  struct Index;
  std::vector<StoredReservoir> items_;
  std::unique_ptr<Index> index_;
  uint64_t placedVersion_ = UINT64_MAX;  // geometry version p and n were computed in
};

}  // namespace invr
