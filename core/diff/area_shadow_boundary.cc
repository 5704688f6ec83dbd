#include "core/diff/area_shadow_boundary.h"

#include <algorithm>

#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"

namespace invr {

AreaShadowBoundary::AreaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool AreaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (emittedPower(l) > 0.f) return true;
  return false;
}

BoundaryPassStats AreaShadowBoundary::run(int view, const Image& adjoint, int samples, int lightPoints, uint64_t stream, uint64_t step,
                                          GradientScratchPool& scratch, std::vector<double>& gradient, const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  std::vector<float> power(scene_.lights.size());
  for (size_t i = 0; i < power.size(); ++i) power[i] = emittedPower(scene_.lights[i]);
  if (samples <= 0 || lightPoints <= 0 || *std::max_element(power.begin(), power.end()) <= 0.f) return {};
  const Distribution1D pickLight(power);
  // The pass's light points: keyed by the step, view and point index (not by thread).
  std::vector<LightPoint> points;
  std::vector<BorderSource> sources;
  for (int j = 0; j < lightPoints; ++j) {
    Sampler s(RngKey{stream, step, uint64_t(view), uint64_t(j), 1});
    const uint32_t li = uint32_t(pickLight.sample(s.next1D()));
    const Light& l = scene_.lights[li];
    float remapped;
    const float u = s.next1D(), v = s.next1D();
    const uint32_t tri = uint32_t(l.triangles.sample(u, &remapped));
    const Vec2 bc = sampleUniformTriangle({remapped, v});
    const SurfaceHit y = scene_.surfaceAt(l.mesh, tri, bc.x, bc.y);
    points.push_back({li, y.p, y.ng, double(pickLight.pmf(li)) / double(l.area)});
    // The density of y_j over the pass's lightPoints draws.
    sources.push_back({ShadowSource::at(y.p), 1.0 / (points.back().pdf * double(lightPoints)), l.mesh});
  }
  return sampleShadowBorders(
      scene_, params_, topology_, view, adjoint, samples, sources,
      [&](uint32_t j, float fx, float fy, RayStats& rays) {
        return pointSourceRadiance(scene_, cam, fx, fy, scene_.lights[points[j].light], points[j], rays);
      },
      stream, step, scratch, gradient, cancel);
}

}  // namespace invr
