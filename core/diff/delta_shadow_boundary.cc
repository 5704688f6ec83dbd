#include "core/diff/delta_shadow_boundary.h"

#include "core/diff/shadow_border.h"

namespace invr {

DeltaShadowBoundary::DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool DeltaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (l.isDelta()) return true;
  return false;
}

BoundaryPassStats DeltaShadowBoundary::run(const InteriorEstimator& /*estimator*/, int view, const Image& adjoint, int samples, uint64_t stream,
                                           uint64_t step, GradientScratchPool& scratch, std::vector<double>& gradient,
                                           const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  std::vector<BorderSource> sources;
  std::vector<const Light*> lights;
  for (const Light& light : scene_.lights) {
    if (!light.isDelta()) continue;
    sources.push_back({ShadowSource::at(light.position)});
    lights.push_back(&light);
  }
  return sampleShadowBorders(
      scene_, params_, topology_, view, adjoint, samples, sources,
      [&](uint32_t j, float fx, float fy, RayStats& rays) { return deltaSourceRadiance(scene_, cam, fx, fy, *lights[j], rays); }, stream,
      step, scratch, gradient, cancel);
}

}  // namespace invr
