#include "core/diff/area_shadow_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"
#include "core/render/direct_light.h"

namespace invr {


AreaShadowBoundary::AreaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool AreaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (emittedPower(l) > 0.f) return true;
  return false;
}

BoundaryPassStats AreaShadowBoundary::run(int view, const Image& adjoint, int samples, int lightPoints, uint64_t stream, uint64_t step,
                                          GradientScratchPool& scratchPool, std::vector<double>& gradient,
                                          const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  BoundaryPassStats st;
  std::vector<float> power(scene_.lights.size());
  for (size_t i = 0; i < power.size(); ++i) power[i] = emittedPower(scene_.lights[i]);
  if (samples <= 0 || lightPoints <= 0 || *std::max_element(power.begin(), power.end()) <= 0.f) return st;
  const Distribution1D pickLight(power);
  // The pass's light points: keyed by the step, view and point index (not by thread).
  std::vector<LightPoint> points;
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
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
    collectShadowEdges(scene_, params_, topology_, ShadowSource::at(y.p), uint32_t(j), edges, weights, l.mesh);
  }
  st.candidateEdges = edges.size();
  if (edges.empty()) return st;
  const Distribution1D pick(weights);

  runBoundarySamples(samples, scratchPool, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler(RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float t = 0.f;
    const size_t k = pick.sample(sampler.next1D(), &t);
    const ShadowEdge& se = edges[k];
    const LightPoint& lp = points[se.source];
    ShadowBorderPoint bp;
    if (!shadowBorderPoint(scene_, params_, cam, ShadowSource::at(lp.y), se, t, bp)) return;
    const Light& l = scene_.lights[lp.light];
    const Rgb minus = pointSourceRadiance(scene_, cam, bp.x.x - bp.eps * bp.n.x, bp.x.y - bp.eps * bp.n.y, l, lp, counters.rays);
    const Rgb plus = pointSourceRadiance(scene_, cam, bp.x.x + bp.eps * bp.n.x, bp.x.y + bp.eps * bp.n.y, l, lp, counters.rays);
    const Rgb diff = minus - plus;
    if (isBlack(diff)) return;
    const int px = std::clamp(int(bp.x.x), 0, scene_.width - 1), py = std::clamp(int(bp.x.y), 0, scene_.height - 1);
    const Rgb adj = adjoint.rgb(px, py);
    // pdf of (j, edge, t) times the density of y_j, over the pass's lightPoints draws.
    const double pdf = double(pick.pmf(k)) * lp.pdf * double(lightPoints);
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(bp.speed) / (pdf * double(samples));
    if (w != 0.0) addShadowBorderGradient(scene_, params_, se, bp, w, grad);
  });
  return st;
}

}  // namespace invr
