#include "core/restir/edge_reservoir.h"

#include <algorithm>

#include "core/geometry/point_kd_tree.h"

namespace invr {

struct EdgeReservoirSet::Index : PointKdIndex {
  explicit Index(std::vector<float> xyz) : PointKdIndex(std::move(xyz), 16) {}
};

EdgeReservoirSet::EdgeReservoirSet() = default;
EdgeReservoirSet::~EdgeReservoirSet() = default;
EdgeReservoirSet::EdgeReservoirSet(EdgeReservoirSet&&) noexcept = default;
EdgeReservoirSet& EdgeReservoirSet::operator=(EdgeReservoirSet&&) noexcept = default;

void EdgeReservoirSet::index(std::vector<Vec3> points) {
  index_.reset();
  if (points.empty()) return;
  std::vector<float> xyz(points.size() * 3);
  for (size_t i = 0; i < points.size(); ++i)
    for (int c = 0; c < 3; ++c) xyz[3 * i + size_t(c)] = points[i][c];
  index_ = std::make_unique<Index>(std::move(xyz));
}

int EdgeReservoirSet::nearest(Vec3 p, float radius, int k, uint32_t* out) const {
  if (!index_ || k <= 0) return 0;
  k = std::min(k, 8);
  uint32_t idx[8];
  float d2[8];
  nanoflann::KNNResultSet<float, uint32_t, size_t> result{size_t(k)};
  result.init(idx, d2);
  const float q[3] = {p.x, p.y, p.z};
  index_->tree.findNeighbors(result, q, nanoflann::SearchParams());
  int n = 0;
  for (size_t i = 0; i < result.size(); ++i)
    if (d2[i] <= radius * radius) out[n++] = idx[i];
  return n;
}

}  // namespace invr
