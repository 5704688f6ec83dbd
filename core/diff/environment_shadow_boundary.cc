#include "core/diff/environment_shadow_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"

namespace invr {

EnvironmentShadowBoundary::EnvironmentShadowBoundary(const Scene& scene, const ParameterRegistry& params,
                                                     const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool EnvironmentShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (l.isInfinite()) return true;
  return false;
}

BoundaryPassStats EnvironmentShadowBoundary::run(int view, const Image& adjoint, int samples, int directions, uint64_t stream, uint64_t step,
                                                 GradientScratchPool& scratchPool, std::vector<double>& gradient,
                                                 const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  BoundaryPassStats st;
  std::vector<uint32_t> environments;
  for (uint32_t i = 0; i < scene_.lights.size(); ++i)
    if (scene_.lights[i].isInfinite()) environments.push_back(i);
  if (samples <= 0 || directions <= 0 || environments.empty()) return st;

  // The pass's directions: keyed by the step, view and direction index (not by thread). A
  // direction the environment gives no radiance or density keeps its slot but no edges.
  struct Direction {
    LightSample ls;
    double pdf = 0;  // solid-angle density of w (environment choice included)
  };
  std::vector<Direction> dirs(static_cast<size_t>(directions));
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
  for (int j = 0; j < directions; ++j) {
    Sampler s(RngKey{stream, step, uint64_t(view), uint64_t(j), 1});
    const size_t pickEnv = std::min(environments.size() - 1, size_t(s.next1D() * float(environments.size())));
    const uint32_t li = environments[pickEnv];
    const float u = s.next1D(), v = s.next1D();
    Direction& d = dirs[size_t(j)];
    d.ls = sampleLight(scene_.lights[li], scene_, Vec3(0.f), Vec2(u, v), li);
    d.pdf = double(d.ls.pdf) / double(environments.size());
    if (!(d.pdf > 0.0) || isBlack(d.ls.radiance)) continue;
    collectShadowEdges(scene_, params_, topology_, ShadowSource::towards(d.ls.wi), uint32_t(j), edges, weights);
  }
  st.candidateEdges = edges.size();
  if (edges.empty()) return st;
  const Distribution1D pick(weights);

  runBoundarySamples(samples, scratchPool, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler(RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float t = 0.f;
    const size_t k = pick.sample(sampler.next1D(), &t);
    const ShadowEdge& se = edges[k];
    const Direction& d = dirs[se.source];
    ShadowBorderPoint bp;
    if (!shadowBorderPoint(scene_, params_, cam, ShadowSource::towards(d.ls.wi), se, t, bp)) return;
    const Rgb minus = directionalSourceRadiance(scene_, cam, bp.x.x - bp.eps * bp.n.x, bp.x.y - bp.eps * bp.n.y, d.ls, counters.rays);
    const Rgb plus = directionalSourceRadiance(scene_, cam, bp.x.x + bp.eps * bp.n.x, bp.x.y + bp.eps * bp.n.y, d.ls, counters.rays);
    const Rgb diff = minus - plus;
    if (isBlack(diff)) return;
    const Rgb adj = adjoint.rgb(std::clamp(int(bp.x.x), 0, scene_.width - 1), std::clamp(int(bp.x.y), 0, scene_.height - 1));
    // pdf of (j, edge, t) times the density of w_j, over the pass's `directions` draws.
    const double pdf = double(pick.pmf(k)) * d.pdf * double(directions);
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(bp.speed) / (pdf * double(samples));
    if (w != 0.0) addShadowBorderGradient(scene_, params_, se, bp, w, grad);
  });
  return st;
}

}  // namespace invr
