// The secondary boundary term for area lights by multi-directional sampling with edge reservoirs
// (Wang et al. 2023, §5.2, Eq. 21-27, Alg. 6 and 8).
//
// A sample picks an edge point p^B first (edge k with probability p_k, t uniform along it), then a
// light point y by streaming RIS over `candidates` light samples (light by emitted power, uniform
// in area) with the target
//     p̂(y) = g(y) (c + h(y)),   g(y) = [edge k is a silhouette from y] Le(y) cos_y / |y - p^B|^2,
// where h(y) = |dL/dI| at the film point of the border y casts through p^B times that border's
// film speed and the receiver's cosine (shadow_border.h; two rays), zero when y is hidden from p^B
// (one more ray), and c > 0 a floor. So the target follows the integrand of Eq. 22 while its
// support is g's alone, which depends only on p^B and the edge's face normals: the support test of
// a reused sample needs just those, as they were where the sample was created (§3.2), and stays
// unbiased when geometry moves.
//
// With reuse, the previous step's edge reservoirs nearest to p^B (kd-tree over their edge points
// re-placed on their edges in the current geometry) are merged with the 1/Z weights of Alg. 3, Z
// counting the reservoirs whose target's support holds y. The sample's contribution is
// F(p^B, y) W / p(p^B) (Eq. 25), F measured as in area_shadow_boundary.h: the point source at y's
// radiance on each side of its shadow border on the film. Unbiased for any p_k > 0.
//
// Edge importance (Eq. 27): p_k ∝ (mean of wSum / M over the previous step's reservoirs on edge k
// + eps) * base_k, base_k the edge's length (times kUnlikelyShadowEdgeWeight when its mesh does
// not move), and 0 for an edge that no point of an emitting area light sees as a silhouette (tested
// against each light's bounding box: such an edge's target is zero for every y); without it,
// p_k ∝ base_k. eps is kEdgeImportanceFloor times the mean over all
// reservoirs, so edges no reservoir landed on keep a share.
#pragma once

#include "core/diff/boundary_sampling.h"
#include "core/diff/boundary_term.h"
#include "core/restir/edge_reservoir.h"

namespace invr {

struct EdgeSamplingSettings {
  int candidates = 8;          // light candidates per edge point (1: plain light sampling, Eq. 21)
  bool reuse = true;           // merge the previous step's edge reservoirs (Alg. 6)
  bool edgeImportance = true;  // p_k from those reservoirs (Eq. 27)
  int neighbours = 0;          // reservoirs merged per sample
  float maxM = 2.f;           // cap on a reused reservoir's M, in units of `candidates`
};

class EdgeReservoirBoundary {
 public:
  static constexpr float kEdgeImportanceFloor = 0.1f;
  // Neighbours are searched within this fraction of the scene's bounding-box diagonal.
  static constexpr float kNeighbourRadius = 0.02f;
  // Reservoirs kept by Alg. 8 are dropped after this many steps (else reservoirs no view sees would
  // pile up for ever).
  static constexpr uint32_t kMaxAge = 8;
  static constexpr int kAdjointRadius = 2;  // pixels: the target's |dL/dI| is a (2r+1)^2 box mean

  // Prepares a step: re-places `previous` in the current geometry, indexes it and builds the edge
  // distribution. `previous` must outlive the object and stay unchanged.
  EdgeReservoirBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                        EdgeReservoirSet& previous, const EdgeSamplingSettings& settings);

  static bool applies(const Scene& scene);  // an area light emits

  // One view's pass. Appends one reservoir per sample (in sample order) to `created`.
  BoundaryPassStats run(int view, const Image& adjoint, int samples, uint64_t stream, uint64_t step, GradientScratchPool& scratch,
                        std::vector<double>& gradient, std::vector<EdgeReservoir>& created, const std::atomic<bool>* cancel = nullptr,
                        PixelDerivativeSink* pixels = nullptr) const;

  // Alg. 8: appends to `next` the previous reservoirs whose p1 none of `views` sees, aged by one
  // (up to kMaxAge). Returns how many.
  size_t preserve(const std::vector<int>& views, std::vector<EdgeReservoir>& next, RayStats& rays) const;

  size_t edgeCount() const { return edges_.size(); }

 private:
  struct EdgeRef {
    uint32_t mesh, edge;
  };
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
  const EdgeReservoirSet& previous_;
  EdgeSamplingSettings settings_;
  std::vector<EdgeRef> edges_;
  std::vector<uint32_t> firstEdge_;  // per mesh: index of its first edge in edges_
  Distribution1D pickEdge_;
  Distribution1D pickLight_;
  float radius_ = 0.f;
  size_t candidateEdges_ = 0;  // edges with p_k > 0 before edge importance (reported per pass)
};

inline constexpr const char* kEdgeFirstAreaShadowsName = "area_shadows_edge_first";

// The edge-first term's options (optimization.boundary.terms.area_shadows_edge_first, with the
// shared fields edge_importance and edge_neighbours as job-wide aliases).
struct EdgeFirstAreaShadowOptions : BoundaryTermOptionsOf<EdgeFirstAreaShadowOptions> {
  static constexpr const char* kTerm = kEdgeFirstAreaShadowsName;
  bool edgeImportance = true;  // restir: edges sampled from the previous step's edge reservoirs (Eq. 27)
  // restir: previous-step edge reservoirs merged per sample (Alg. 6). 0: they steer edge importance
  // only; merging measured no gain (docs/shapes.md).
  int edgeNeighbours = 0;
};

// What the edge-first term keeps between steps, in its slot of the session (boundary_state.h).
struct EdgeReservoirState final : BoundaryTermState {
  EdgeReservoirSet edges;
};
// The edge reservoirs a session's slots hold for the term, or null before it kept any.
const EdgeReservoirSet* keptEdgeReservoirs(const BoundaryStateSlots& session);

}  // namespace invr
