// The secondary boundary term for point and spot lights (the paper's multi-directional form,
// Eq. 21-26, covers area lights only; this estimator is ours). A delta light's shadow border on
// a receiver is where rays from the light graze an occluder's silhouette edge (silhouette as seen
// from the light); shadow_border.h parametrises its film image by the occluder edge. Across it the
// whole radiance jumps, so a sample picks a (light, edge) pair by the weights of
// collectShadowEdges, t uniformly, traces one camera sample on each side of the border point with
// the job's interior estimator, and weighs the difference by dLoss/dI of its pixel. Borders hidden
// from the camera or lying in another shadow need no test: both sides then see the same radiance.
#pragma once

#include "core/diff/primary_boundary.h"

namespace invr {

class DeltaShadowBoundary {
 public:
  // topology[m] for every mesh (occluders may be static: a moving receiver moves their shadow).
  DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology);

  // Whether the scene has a point or spot light (else the estimator has nothing to do).
  static bool applies(const Scene& scene);

  BoundaryPassStats run(const InteriorEstimator& estimator, int view, const Image& adjoint, int samples, uint64_t stream, uint64_t step,
                        GradientScratchPool& scratch, std::vector<double>& gradient, const std::atomic<bool>* cancel = nullptr) const;

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
};

}  // namespace invr
