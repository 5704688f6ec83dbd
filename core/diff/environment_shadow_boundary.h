// The secondary boundary term for environment lights (ours: the paper's Eq. 21-26 cover area
// lights). An environment's image is the integral over directions w of the image a source at
// infinity in direction w (radiance Le(w) per unit solid angle) makes, so the derivative of its
// visibility is the integral over w of that directional source's shadow-border term
// (shadow_border.h, with the travel direction -w in place of l -> e). A pass draws `directions`
// directions w_j by the environment's own sampling (an environment light uniformly, then w by its
// importance map; uniform on the sphere for a constant one), collects each one's silhouette edges,
// and samples (j, edge, t) from the union. The jump across the border is that direction's
// contribution f |cos| Le on each side, evaluated directly (one shadow ray a side),
// so no other light's noise enters it. Unbiased for any number of directions >= 1.
#pragma once

#include "core/diff/boundary_sampling.h"
#include "core/diff/boundary_term.h"

namespace invr {

inline constexpr StreamId kEnvironmentShadowBoundaryStream{15};  // pinned: the stream its documented figures used (BoundaryTermKind::pinnedStream)

// The term's options (optimization.boundary.terms.environment_shadows).
struct EnvironmentShadowOptions : BoundaryTermOptionsOf<EnvironmentShadowOptions> {
  static constexpr const char* kTerm = "environment_shadows";
  int directions = 0;  // per pass; 0: BoundaryOptions::lightPoints
  int directionsOf(const BoundaryOptions& b) const { return directions > 0 ? directions : b.lightPoints; }
};

class EnvironmentShadowBoundary final : public BoundaryTerm {
 public:
  EnvironmentShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology, int directions);

  // Whether the scene has an environment light (else the estimator has nothing to do).
  static bool applies(const Scene& scene);

  BoundaryPassStats run(const BoundaryView& view) override;

 private:
  int directions_;
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
};

}  // namespace invr
