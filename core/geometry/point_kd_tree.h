// A nanoflann kd-tree over a packed copy of 3-D points (the reservoir store's shading points, the
// edge reservoirs' edge points): the build and every search touch 12 bytes per point instead of a
// whole reservoir.
#pragma once

#include <nanoflann.hpp>

#include <cstdint>
#include <vector>

namespace invr {

struct PackedPoints {
  std::vector<float> xyz;  // x, y, z of each point
  size_t kdtree_get_point_count() const { return xyz.size() / 3; }
  float kdtree_get_pt(size_t i, size_t dim) const { return xyz[3 * i + dim]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};

using PointKdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PackedPoints>, PackedPoints, 3, uint32_t>;

// The points and their tree. The tree refers to the points: never copied or moved (held through
// unique_ptr).
struct PointKdIndex {
  PackedPoints cloud;
  PointKdTree tree;
  PointKdIndex(std::vector<float> xyz, size_t leafSize) : cloud{std::move(xyz)}, tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leafSize)) {
    tree.buildIndex();
  }
};

}  // namespace invr
