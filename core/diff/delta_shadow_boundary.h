// The secondary boundary term for point and spot lights (the paper's multi-directional form,
// Eq. 21-26, covers area lights only; this estimator is ours). A delta light's shadow border on
// a receiver is where rays from the light graze an occluder's silhouette edge (silhouette as seen
// from the light). Its film image is a curve across which what a pixel sees jumps, so by the same
// Reynolds transport as the primary term
//     d/dtheta sum_p w_p I_p = ∫ w(x) (L(x - eps n) - L(x + eps n)) (v . n) dl   over that curve.
// We parametrise the curve by the occluder edge: edge point e(t) = a + t (b - a), shadow point
// y(t) = first surface the ray light -> e(t) meets beyond e, film point x(t) = proj(y). Then
// (v . n) dl = (v . perp(dx/dt)) dt, and dy/dtheta follows from the ray-plane intersection at y
// with the occluder's velocity at e and the receiver's at y (either or both may move).
//
// A sample picks a (light, edge) pair with probability proportional to the edge's length among
// the silhouette edges from each delta light, times kUnlikelyEdgeWeight when a ray through its
// midpoint finds no receiver, and again when neither the edge's mesh nor that receiver moves, t uniformly, traces one camera sample on each side
// of x with the job's interior estimator, and weighs by dLoss/dI of x's pixel. Borders hidden from
// the camera or lying in another shadow need no test: both sides then see the same radiance.
#pragma once

#include "core/diff/primary_boundary.h"

namespace invr {

class DeltaShadowBoundary {
 public:
  // topology[m] for every mesh (occluders may be static: a moving receiver moves their shadow).
  DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology);

  static constexpr float kUnlikelyEdgeWeight = 0.05f;

  BoundaryPassStats run(const InteriorEstimator& estimator, int view, const Image& adjoint, int samples, uint64_t stream, uint64_t step,
                        GradientScratchPool& scratch, std::vector<double>& gradient, const std::atomic<bool>* cancel = nullptr) const;

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
};

}  // namespace invr
