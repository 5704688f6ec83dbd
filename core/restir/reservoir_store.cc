#include "core/restir/reservoir_store.h"

#include <algorithm>

#include "core/error.h"
#include "core/geometry/point_kd_tree.h"

namespace invr {

namespace {

// The first `capacity` points found within a radius. The search descends to the query's own leaf
// first, so these are near the query (usually the closest few), and it stops as soon as it has
// them instead of backtracking to prove they are the nearest: most queries read one leaf.
// Unbiasedness does not need the nearest: any choice that depends only on the stored shading
// points (not on their light samples) keeps the combination unbiased.
class FirstWithinRadius {
 public:
  using DistanceType = float;
  using IndexType = uint32_t;
  using CountType = size_t;
  FirstWithinRadius(size_t capacity, float radius2, uint32_t* indices, float* dists)
      : indices_(indices), dists_(dists), capacity_(capacity), radius2_(radius2) {}
  size_t size() const { return count_; }
  bool full() const { return count_ == capacity_; }
  bool addPoint(float dist, uint32_t index) {  // only called for dist < worstDist()
    indices_[count_] = index;
    dists_[count_] = dist;
    return ++count_ < capacity_;  // false ends the search
  }
  float worstDist() const { return radius2_; }

 private:
  uint32_t* indices_;
  float* dists_;
  size_t capacity_, count_ = 0;
  float radius2_;
};

}  // namespace

struct ReservoirStore::Index : PointKdIndex {
  explicit Index(const std::vector<StoredReservoir>& items) : PointKdIndex(packed(items), 64) {}
  static std::vector<float> packed(const std::vector<StoredReservoir>& items) {
    std::vector<float> xyz(items.size() * 3);
    for (size_t i = 0; i < items.size(); ++i)
      for (int c = 0; c < 3; ++c) xyz[3 * i + size_t(c)] = items[i].p[c];
    return xyz;
  }
};

ReservoirStore::ReservoirStore() = default;
ReservoirStore::~ReservoirStore() = default;
ReservoirStore::ReservoirStore(ReservoirStore&& o) noexcept
    : items_(std::move(o.items_)),
      recycled_(std::move(o.recycled_)),
      slots_(std::move(o.slots_)),
      slotsComplete_(o.slotsComplete_),
      placedVersion_(o.placedVersion_) {
  o.index_.reset();
  o.indexOnce_ = std::make_unique<std::once_flag>();
}
ReservoirStore& ReservoirStore::operator=(ReservoirStore&& o) noexcept {
  items_ = std::move(o.items_);
  recycled_ = std::move(o.recycled_);
  slots_ = std::move(o.slots_);
  slotsComplete_ = o.slotsComplete_;
  placedVersion_ = o.placedVersion_;
  index_.reset();
  indexOnce_ = std::make_unique<std::once_flag>();
  o.index_.reset();
  o.indexOnce_ = std::make_unique<std::once_flag>();
  return *this;
}

void ReservoirStore::keepReferencedPoses() {
  if (poses_.empty()) return;
  // Keep the geometries some item was created in, renumbered in their old (creation) order.
  std::vector<uint16_t> renumber(poses_.size(), UINT16_MAX);
  for (const StoredReservoir& q : items_)
    INVR_INVARIANT(q.pose < poses_.size(), "a stored reservoir refers to a geometry the store never recorded");
  for (const StoredReservoir& q : items_) renumber[q.pose] = 0;
  std::vector<PoseSnapshot> kept;
  for (size_t i = 0; i < poses_.size(); ++i)
    if (renumber[i] == 0) {
      renumber[i] = uint16_t(kept.size());
      kept.push_back(std::move(poses_[i]));
    }
  for (StoredReservoir& q : items_) q.pose = renumber[q.pose];
  poses_ = std::move(kept);
  currentPose_ = uint16_t(poses_.size());  // refresh() records the next geometry
}

void ReservoirStore::assign(std::vector<StoredReservoir> items) {
  recycled_ = std::move(items_);
  items_ = std::move(items);
  keepReferencedPoses();
  slots_ = PixelSlots();
  slotsComplete_ = false;
  placedVersion_ = UINT64_MAX;
  index_.reset();
  indexOnce_ = std::make_unique<std::once_flag>();
}

void ReservoirStore::assignPlaced(std::vector<StoredReservoir> items, uint64_t geometryVersion, PixelSlots slots) {
  recycled_ = std::move(items_);
  items_ = std::move(items);
  keepReferencedPoses();
  slots_ = std::move(slots);
  size_t indexed = 0;
  for (uint32_t i : slots_.item) indexed += i != UINT32_MAX;
  slotsComplete_ = slots_.views.size() == 1 && indexed == items_.size();
  placedVersion_ = geometryVersion;
  index_.reset();
  indexOnce_ = std::make_unique<std::once_flag>();
}

void ReservoirStore::refresh(const Scene& scene) {
  if (scene.motion.anyMoving()) {
    if (poses_.empty() || poses_.back().version != scene.geometryVersion()) {
      // At most one geometry per step survives into the table, and a preserved item keeps its own
      // alive: past 60000 of them, the oldest items go (their geometry is dropped with them).
      if (poses_.size() >= 60000) {
        const uint16_t oldest = 0;
        std::erase_if(items_, [&](const StoredReservoir& q) { return q.pose == oldest; });
        for (StoredReservoir& q : items_) --q.pose;
        poses_.erase(poses_.begin());
        slots_ = PixelSlots();
        slotsComplete_ = false;
      }
      poses_.push_back(scene.pose());
    }
    currentPose_ = uint16_t(poses_.size() - 1);
  }
  if (placedVersion_ != scene.geometryVersion()) {
    for (auto& s : items_) {
      SurfaceHit h = scene.surfaceAt(s.mesh, s.tri, s.b1, s.b2);
      s.p = h.p;
      s.setNormal(h.ns);
    }
    placedVersion_ = scene.geometryVersion();
    slotsComplete_ = false;  // moved points may now lie anywhere on screen
  }
  index_.reset();
  indexOnce_ = std::make_unique<std::once_flag>();
}

const ReservoirStore::Index& ReservoirStore::index() const {
  std::call_once(*indexOnce_, [this] { index_ = std::make_unique<Index>(items_); });
  return *index_;
}

const uint32_t* ReservoirStore::pixelSlots(int view) const {
  for (size_t k = 0; k < slots_.views.size(); ++k)
    if (slots_.views[k] == view) return slots_.item.data() + k * slots_.slotsPerView;
  return nullptr;
}

bool ReservoirStore::slotsCover(int view) const { return slotsComplete_ && slots_.views[0] == view; }

int ReservoirStore::neighbours(Vec3 p, Vec3 n, int k, float radius, float normalDot, uint32_t* out,
                               const NeighbourHints* hints) const {
  if (items_.empty() || k <= 0) return 0;
  const float r2 = radius * radius;
  int count = 0;
  auto taken = [&](uint32_t i) { return std::find(out, out + count, i) != out + count; };
  auto acceptable = [&](uint32_t i) { return i < items_.size() && dot(items_[i].n(), n) >= normalDot && !taken(i); };
  for (int h = 0; hints && h < hints->count; ++h) {
    uint32_t i = hints->items[h];
    if (acceptable(i) && lengthSquared(items_[i].p - p) <= r2) {
      out[count++] = i;
      if (count == k) return count;  // no search at all: the usual case with one neighbour
    }
  }
  // Candidates from a search, closest first (insertion into a short sorted list).
  constexpr int kMaxQuery = 32;
  const int want = std::min(kMaxQuery, 2 * k);
  uint32_t idx[kMaxQuery];
  float d2[kMaxQuery];
  size_t found = 0;
  auto consider = [&](uint32_t i, float d) {
    if (found == size_t(want) && d >= d2[found - 1]) return;
    size_t j = found < size_t(want) ? found++ : found - 1;
    for (; j > 0 && d2[j - 1] > d; --j) {
      d2[j] = d2[j - 1];
      idx[j] = idx[j - 1];
    }
    d2[j] = d;
    idx[j] = i;
  };
  if (hints && hints->slots) {
    for (int y = std::max(0, hints->y - hints->half); y <= std::min(hints->height - 1, hints->y + hints->half); ++y)
      for (int x = std::max(0, hints->x - hints->half); x <= std::min(hints->width - 1, hints->x + hints->half); ++x)
        for (int s = 0; s < hints->spp; ++s) {
          uint32_t i = hints->slots[(size_t(y) * size_t(hints->width) + size_t(x)) * size_t(hints->spp) + size_t(s)];
          if (!acceptable(i)) continue;
          float d = lengthSquared(items_[i].p - p);
          if (d <= r2) consider(i, d);
        }
  } else {
    uint32_t kdIdx[kMaxQuery];
    float kdD2[kMaxQuery];
    float q[3] = {p.x, p.y, p.z};
    FirstWithinRadius result(size_t(want), r2, kdIdx, kdD2);
    index().tree.findNeighbors(result, q, nanoflann::SearchParams());
    for (size_t j = 0; j < result.size(); ++j)
      if (acceptable(kdIdx[j])) consider(kdIdx[j], kdD2[j]);
  }
  for (size_t j = 0; j < found && count < k; ++j) out[count++] = idx[j];
  return count;
}

}  // namespace invr
