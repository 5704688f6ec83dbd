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

  std::vector<StoredReservoir> items;

  // Re-places every shading point (and light sample, lazily on use) on the current geometry and
  // rebuilds the kd-tree. Call after parameters change and before neighbours().
  void refresh(const Scene& scene);
  // Up to k nearest reservoirs within `radius` of p whose normal n' has dot(n, n') >= normalDot.
  // Returns how many indices were written to out (which must hold k entries).
  int neighbours(Vec3 p, Vec3 n, int k, float radius, float normalDot, uint32_t* out) const;
  bool empty() const { return items.empty(); }

 private:
  struct Index;
  std::unique_ptr<Index> index_;
};

}  // namespace invr
