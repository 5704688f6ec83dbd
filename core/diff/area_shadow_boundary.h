// The secondary boundary term for area lights (Wang et al. 2023, §5, Eq. 21-26): shadow borders
// that moving occluders or receivers drag across the film. An area light's image is the integral
// over its points y of the image a point source at y (intensity Le(y) |cos_y| dA) makes, so the
// derivative of its visibility is the integral over y of that point source's shadow-border term
// (shadow_border.h). A pass draws `lightPoints` points y_j (light by emitted power, uniform in
// area), collects each one's silhouette edges, and samples (j, edge, t) from the union; the jump
// across the border is that source's contribution on each side, evaluated directly (two camera
// rays and two shadow rays: the rest of the radiance is continuous there), so there is no
// light-sampling noise in it. Unbiased for any lightPoints >= 1; more points spread the samples
// over more of the penumbra.
//
// This is AREA_SAMPLING_LIGHT_POINTS; the default samples an edge point first and reuses edge
// reservoirs across steps (edge_reservoir_boundary.h: Alg. 6, Eq. 27, Alg. 8).
#pragma once

#include "core/diff/boundary_sampling.h"
#include "core/diff/boundary_term.h"

namespace invr {

// Area-light shadow borders (light points first, or edge first: edge_reservoir_boundary.h).
inline constexpr StreamId kAreaShadowBoundaryStream{14};  // pinned: the stream its documented figures used (BoundaryTermKind::pinnedStream)

// The light-points-first term's options (optimization.boundary.terms.area_shadows_light_points).
struct LightPointsAreaShadowOptions : BoundaryTermOptionsOf<LightPointsAreaShadowOptions> {
  static constexpr const char* kTerm = "area_shadows_light_points";
  int lightPoints = 0;  // per pass; 0: BoundaryOptions::lightPoints
  int lightPointsOf(const BoundaryOptions& b) const { return lightPoints > 0 ? lightPoints : b.lightPoints; }
};

class AreaShadowBoundary final : public BoundaryTerm {
 public:
  AreaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology, int lightPoints);

  // Whether the scene has an area light that emits (else the estimator has nothing to do).
  static bool applies(const Scene& scene);

  BoundaryPassStats run(const BoundaryView& view) override;

 private:
  int lightPoints_;
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
};

}  // namespace invr
