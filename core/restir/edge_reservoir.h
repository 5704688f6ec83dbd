// Edge reservoirs (Wang et al. 2023, Alg. 6): one per secondary-boundary sample of a step, kept
// for the next step's samples to reuse. A reservoir is anchored to its edge point p^B as (mesh,
// welded edge, t), so it is re-placed on the edge when geometry moves, and holds its light sample
// y as (light, triangle, barycentrics). It also keeps what its target's support was where it was
// created (p^B and the normals of the edge's faces then): the support test of a reused sample is
// made in the geometry it was created in (§3.2), as for the interior reservoirs.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/math/vec.h"

namespace invr {

struct EdgeReservoir {
  uint32_t mesh = 0, edge = 0;  // the welded edge p^B lies on (an EdgeTopology index)
  float t = 0.f;                // where along it, from the edge's v0
  uint32_t light = 0, tri = 0;  // the light sample y: the light and a triangle of its mesh
  float b0 = 0.f, b1 = 0.f;     // barycentrics of y on that triangle
  double wSum = 0.0;            // sum of resampling weights (Eq. 27 reads wSum / M)
  float M = 0.f;                // candidates represented
  float W = 0.f;                // unbiased contribution weight of y; 0: no sample
  uint32_t age = 0;             // steps since it was created (Alg. 8 survivors age)
  // Where it was created: p^B and the normals of the edge's two faces (equal for a boundary edge,
  // which is a silhouette from every point: `single`).
  Vec3 pB, nA, nB;
  bool single = false;
  // Where the shadow ray from y through p^B landed (Alg. 8 keeps reservoirs whose p1 no camera of
  // the step's batch sees).
  bool hasP1 = false;
  Vec3 p1;
};

// A step's edge reservoirs and a kd-tree over points the caller gives for them (their p^B
// re-placed in the current geometry).
class EdgeReservoirSet {
 public:
  EdgeReservoirSet();
  ~EdgeReservoirSet();
  EdgeReservoirSet(EdgeReservoirSet&&) noexcept;
  EdgeReservoirSet& operator=(EdgeReservoirSet&&) noexcept;

  std::vector<EdgeReservoir> items;

  // Builds the neighbour index over points[i] (the position of items[i]); invalidated by any
  // change to `items`.
  void index(std::vector<Vec3> points);
  // Up to `k` (at most 8) of the indexed items nearest to p within `radius`, nearest first.
  // Returns how many were written to out.
  int nearest(Vec3 p, float radius, int k, uint32_t* out) const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;
};

}  // namespace invr
