#include "core/diff/render_cost.h"

#include <algorithm>

namespace invr {

RenderCost renderCostByDepth(const RayStats& rays, const std::vector<float>& survival) {
  RenderCost c;
  if (rays.camera == 0) return c;
  const double n = double(rays.camera);
  c.dSurvival.assign(survival.size(), 0.0);
  for (int d = 0; d <= kMaxWalkDepth; ++d) {
    const double perSample = double(rays.byDepth[d]) / n;
    c.raysPerSample += perSample;
    if (perSample == 0.0 || survival.empty()) continue;
    // The decisions before depth d are those after vertices 0 .. d-1.
    for (int k = 0; k < d; ++k) {
      const size_t i = std::min(size_t(k), survival.size() - 1);
      if (survival[i] > 0.f) c.dSurvival[i] += perSample / double(survival[i]);
    }
  }
  return c;
}

}  // namespace invr
