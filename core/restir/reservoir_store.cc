#include "core/restir/reservoir_store.h"

#include <nanoflann.hpp>

namespace invr {

namespace {

struct PointCloud {
  const std::vector<StoredReservoir>* items = nullptr;
  size_t kdtree_get_point_count() const { return items->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return (*items)[i].p[int(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloud>, PointCloud, 3, uint32_t>;

}  // namespace

struct ReservoirStore::Index {
  PointCloud cloud;
  KdTree tree;
  explicit Index(const std::vector<StoredReservoir>* items)
      : cloud{items}, tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {
    tree.buildIndex();
  }
};

ReservoirStore::ReservoirStore() = default;
ReservoirStore::~ReservoirStore() = default;
ReservoirStore::ReservoirStore(ReservoirStore&& o) noexcept : items_(std::move(o.items_)), placedVersion_(o.placedVersion_) {
  o.index_.reset();
}
ReservoirStore& ReservoirStore::operator=(ReservoirStore&& o) noexcept {
  items_ = std::move(o.items_);
  placedVersion_ = o.placedVersion_;
  index_.reset();
  o.index_.reset();
  return *this;
}

void ReservoirStore::assign(std::vector<StoredReservoir> items) {
  items_ = std::move(items);
  placedVersion_ = UINT64_MAX;
  index_.reset();
}

void ReservoirStore::assignPlaced(std::vector<StoredReservoir> items, uint64_t geometryVersion) {
  items_ = std::move(items);
  placedVersion_ = geometryVersion;
  index_.reset();
}

void ReservoirStore::refresh(const Scene& scene) {
  if (placedVersion_ != scene.geometryVersion()) {
    for (auto& s : items_) {
      SurfaceHit h = scene.surfaceAt(s.mesh, s.tri, s.b1, s.b2);
      s.p = h.p;
      s.n = h.ns;
    }
    placedVersion_ = scene.geometryVersion();
  }
  index_.reset();
  if (!items_.empty()) index_ = std::make_unique<Index>(&items_);
}

int ReservoirStore::neighbours(Vec3 p, Vec3 n, int k, float radius, float normalDot, uint32_t* out) const {
  if (!index_ || k <= 0) return 0;
  // Ask for a few extra so that normal rejection still leaves k candidates most of the time.
  constexpr int kMaxQuery = 32;
  int want = std::min(kMaxQuery, 2 * k);
  uint32_t idx[kMaxQuery];
  float d2[kMaxQuery];
  float q[3] = {p.x, p.y, p.z};
  size_t found = index_->tree.knnSearch(q, size_t(want), idx, d2);
  int count = 0;
  for (size_t i = 0; i < found && count < k; ++i) {
    if (d2[i] > radius * radius) break;  // sorted by distance
    if (dot(items_[idx[i]].n, n) < normalDot) continue;
    out[count++] = idx[i];
  }
  return count;
}

}  // namespace invr
