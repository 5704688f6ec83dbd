// Reservoirs from the previous gradient step, anchored on surfaces (Wang et al. 2023, §4.2):
// each keeps its shading point as (triangle, barycentrics) so it follows the geometry when
// parameters change, and a kd-tree over the current shading points finds reuse candidates.
// When the previous step rendered the query's own view, last step's pixels around the query are
// searched instead (the same candidates, no tree to build).
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <vector>

#include "core/render/reservoir.h"
#include "core/scene/scene.h"

namespace invr {

// What reuse reads of a finished reservoir: its sample, unbiased contribution weight W and
// confidence M (the running sum and target only matter while it is being built).
struct StoredSample {
  LightSampleRef y;
  float W = 0.f;
  float M = 0.f;
  StoredSample() = default;
  explicit StoredSample(const Reservoir& r) : y(r.y), W(r.W), M(r.M) {}
};

// One cache line per reservoir: the neighbour test, the combination and the support test of a
// reuse each read one line (they are random reads into last step's buffer, mostly cache misses).
struct alignas(64) StoredReservoir {
  StoredSample r;
  uint32_t mesh = 0, tri = 0;
  float b1 = 0.f, b2 = 0.f;
  Vec3 p;  // derived from the anchor by refresh()
  // The shading normal (derived by refresh()), 16-bit fixed point: it only serves the normal
  // similarity test and Alg. 8's ray offset.
  int16_t nq[3] = {0, 0, 0};
  // The view whose camera saw it: its BSDF target looks towards that camera's eye.
  uint16_t view = 0;
  // Shadow rays from this point to delta lights 0..7 traced when it was created (bit i: light i
  // known, and visible). They describe the geometry it was created in, which is where support tests
  // ask (§3.2), so those need no new ray.
  uint8_t deltaKnown = 0, deltaVisible = 0;
  // The geometry it was created in (ReservoirStore::poseOf; set from createdPose() of the store
  // the pass reused): the support test of a reuse evaluates its target there (§3.2).
  uint16_t pose = 0;

  Vec3 n() const { return Vec3(float(nq[0]), float(nq[1]), float(nq[2])) * (1.f / 32767.f); }
  void setNormal(Vec3 v) {
    // Rounds half away from zero, as lround does, without its libm call (6 % of ReSTIR's extra
    // instructions over RIS on oxalis).
    for (int c = 0; c < 3; ++c) {
      float x = std::clamp(v[c], -1.f, 1.f) * 32767.f;
      nq[c] = int16_t(x >= 0.f ? x + 0.5f : x - 0.5f);
    }
  }
};
static_assert(sizeof(StoredReservoir) == 64, "a stored reservoir should fill one cache line");

// Which stored item each pixel sample of a pass produced: item[k * slotsPerView + slot] for the
// k-th of `views` (UINT32_MAX: it stored none, e.g. a miss or a pixel outside the mini-batch).
struct PixelSlots {
  std::vector<int> views;
  size_t slotsPerView = 0;
  std::vector<uint32_t> item;
};

// What the caller knows about where to look before (or instead of) the kd-tree.
struct NeighbourHints {
  const uint32_t* items = nullptr;  // items to try first, in order (UINT32_MAX entries are skipped)
  int count = 0;
  // Set only if slotsCover(query's view): that view's pixelSlots and the query's pixel. Every
  // sample of the pixels within `half` of (x, y) is searched instead of the kd-tree.
  const uint32_t* slots = nullptr;
  int x = 0, y = 0, width = 0, height = 0, spp = 1, half = 0;
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
  // `slots` (optional) says which item each pixel sample of each view left behind.
  void assignPlaced(std::vector<StoredReservoir> items, uint64_t geometryVersion, PixelSlots slots = {});
  // The buffer the contents before the last assign lived in, for the caller to fill with the next
  // contents: steps reuse two buffers instead of allocating new pages. It still holds those old
  // items (clearing it would make the caller's resize construct every slot again, several MB a
  // step), so the caller must overwrite every element it keeps.
  std::vector<StoredReservoir> takeRecycled() { return std::move(recycled_); }

  // Re-places every shading point on the current geometry if it moved since the points were
  // placed (light samples are re-placed lazily, on use) and drops the kd-tree, which the first
  // search that needs it rebuilds. Call before neighbours() whenever items or the scene changed.
  void refresh(const Scene& scene);

  // Up to k reservoirs within `radius` of p whose normal n' has dot(n, n') >= normalDot: first the
  // acceptable ones among hints->items, then the closest of those found in the pixel window (when
  // slotsCover) or the closest of the first few the kd-tree finds. Returns how many indices were
  // written to out (which must hold k entries). Safe to call from many threads at once.
  int neighbours(Vec3 p, Vec3 n, int k, float radius, float normalDot, uint32_t* out,
                 const NeighbourHints* hints = nullptr) const;
  // The items the pixel samples of `view` left behind (indexed by pixel * spp + sample), or null
  // if the last assign did not record that view.
  const uint32_t* pixelSlots(int view) const;
  // True if every item was left behind by `view`'s pixel samples (one view, nothing preserved)
  // and the geometry has not moved since: then a window of pixelSlots(view) around a query holds
  // every item that can lie within the reuse radius.
  bool slotsCover(int view) const;
  bool empty() const { return items_.empty(); }
  // The geometry this step's new reservoirs are created in (refresh() records it): what they set
  // as their `pose`. Only kept while some mesh moves (shape jobs).
  uint16_t createdPose() const { return currentPose_; }
  // The geometry item q was created in, or null when no mesh moves (then it is the current one).
  const PoseSnapshot* poseOf(const StoredReservoir& q) const { return q.pose < poses_.size() ? &poses_[q.pose] : nullptr; }
  size_t poseCount() const { return poses_.size(); }

  // Whether a kd-tree is built at the moment (it is built on first need after refresh()).
  bool hasIndex() const { return index_ != nullptr; }
  // Builds the kd-tree now rather than on first need.
  void buildIndex() const { index(); }

 private:
  struct Index;
  const Index& index() const;
  void keepReferencedPoses();
  std::vector<StoredReservoir> items_, recycled_;
  PixelSlots slots_;
  bool slotsComplete_ = false;  // slots_ index every item, placed where they were stored
  mutable std::unique_ptr<Index> index_;
  mutable std::unique_ptr<std::once_flag> indexOnce_ = std::make_unique<std::once_flag>();
  uint64_t placedVersion_ = UINT64_MAX;  // geometry version p and n were computed in
  // The geometries items were created in, those some item still refers to (assignPlaced() drops
  // the rest and renumbers), plus the current one.
  std::vector<PoseSnapshot> poses_;
  uint16_t currentPose_ = 0;
};

}  // namespace invr
