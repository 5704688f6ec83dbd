#include "core/diff/delta_shadow_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"

namespace invr {

DeltaShadowBoundary::DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool DeltaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (l.isDelta()) return true;
  return false;
}

BoundaryPassStats DeltaShadowBoundary::run(const InteriorEstimator& /*estimator*/, int view, const Image& adjoint, int samples, uint64_t stream,
                                           uint64_t step, GradientScratchPool& scratchPool, std::vector<double>& gradient,
                                           const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  BoundaryPassStats st;
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
  std::vector<const Light*> sources;
  for (const Light& light : scene_.lights) {
    if (!light.isDelta()) continue;
    collectShadowEdges(scene_, params_, topology_, ShadowSource::at(light.position), uint32_t(sources.size()), edges, weights);
    sources.push_back(&light);
  }
  st.candidateEdges = edges.size();
  if (edges.empty() || samples <= 0) return st;
  const Distribution1D pick(weights);

  runBoundarySamples(samples, scratchPool, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler(RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float t = 0.f;
    const size_t k = pick.sample(sampler.next1D(), &t);
    const ShadowEdge& se = edges[k];
    ShadowBorderPoint bp;
    const Light& light = *sources[se.source];
    if (!shadowBorderPoint(scene_, params_, cam, ShadowSource::at(light.position), se, t, bp)) return;
    // pdf of (edge, t): the edge's probability (t is uniform on [0, 1]).
    const double pdf = double(pick.pmf(k));
    const Rgb minus = deltaSourceRadiance(scene_, cam, bp.x.x - bp.eps * bp.n.x, bp.x.y - bp.eps * bp.n.y, light, counters.rays);
    const Rgb plus = deltaSourceRadiance(scene_, cam, bp.x.x + bp.eps * bp.n.x, bp.x.y + bp.eps * bp.n.y, light, counters.rays);
    const Rgb adj = adjoint.rgb(std::clamp(int(bp.x.x), 0, scene_.width - 1), std::clamp(int(bp.x.y), 0, scene_.height - 1));
    const Rgb diff = minus - plus;
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(bp.speed) / (pdf * double(samples));
    if (w != 0.0) addShadowBorderGradient(scene_, params_, se, bp, w, grad);
  });
  return st;
}

}  // namespace invr
