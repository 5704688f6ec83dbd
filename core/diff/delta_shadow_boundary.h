// The secondary boundary term for point and spot lights (the paper's multi-directional form,
// Eq. 21-26, covers area lights only; this estimator is ours). A delta light's shadow border on
// a receiver is where rays from the light graze an occluder's silhouette edge (silhouette as seen
// from the light); shadow_border.h parametrises its film image by the occluder edge. A sample
// picks a (light, edge) pair by the weights of collectShadowEdges and t uniformly, and weighs the
// jump of that one light's radiance across the border (deltaSourceRadiance on each side, points of
// the receiver's plane: exact, one shadow ray a side) by dLoss/dI of its pixel. Only that light's jump:
// the whole radiance difference the job's estimator measured there also held the other lights'
// noise and whatever other discontinuity lay under a border point (on the knot under its point
// fills this term read 1.91e-3 that way, 1.74e-3 now). Borders hidden from the camera, or on the
// side of the receiver the light does not reach, are skipped.
#pragma once

#include "core/diff/boundary_sampling.h"
#include "core/diff/boundary_term.h"

namespace invr {

inline constexpr StreamId kDeltaShadowBoundaryStream{13};  // pinned: the stream its documented figures used (BoundaryTermKind::pinnedStream)

class DeltaShadowBoundary final : public BoundaryTerm {
 public:
  // topology[m] for every mesh (occluders may be static: a moving receiver moves their shadow).
  DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology);

  // Whether the scene has a point or spot light (else the estimator has nothing to do).
  static bool applies(const Scene& scene);

  BoundaryPassStats run(const BoundaryView& view) override;

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
};

}  // namespace invr
