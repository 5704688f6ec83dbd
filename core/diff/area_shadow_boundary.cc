#include "core/diff/area_shadow_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"
#include "core/render/direct_light.h"

namespace invr {

namespace {

float emittedPower(const Light& l) { return l.kind == LightKind::Area ? luminance(l.radiance) * l.scale * l.area : 0.f; }

struct LightPoint {
  uint32_t light;
  Vec3 y, n;
  double pdf;  // area density of y (light choice included)
};

// What the point source at y (a point of area light l) adds to the film sample through (fx, fy):
// f |cos_x| Le(y) |cos_y| / r^2, visibility included.
Rgb pointSourceRadiance(const Scene& scene, const Camera& cam, float fx, float fy, const Light& l, const LightPoint& lp, RayStats& rays) {
  const Vec3 d = cam.direction(fx, fy, scene.width, scene.height);
  SurfaceHit hit;
  ++rays.camera;
  if (!scene.intersect(cam.eye, d, hit) || scene.meshLight[hit.mesh] >= 0) return Rgb(0.f);
  const Bsdf bsdf = scene.materials[size_t(scene.meshMaterial[hit.mesh])].at(hit.uv);
  ShadingPoint sp{&hit, &bsdf, Frame(hit.ns), Vec3(), -d};
  sp.wo = sp.frame.toLocal(-d);
  const Vec3 r = lp.y - hit.p;
  const float dist2 = lengthSquared(r);
  if (!(dist2 > 0.f)) return Rgb(0.f);
  const Vec3 wi = r / std::sqrt(dist2);
  const Rgb f = bsdfTowards(sp, wi), Le = areaEmission(l, lp.n, -wi);
  if (isBlack(f) || isBlack(Le)) return Rgb(0.f);
  Vec3 dir;
  float tmax;
  ++rays.shadow;
  if (scene.occludedSegment(Scene::shadowOrigin(hit.p, hit.ng, wi), offsetOrigin(lp.y, lp.n, -wi), dir, tmax)) return Rgb(0.f);
  return f * Le * (std::abs(dot(lp.n, wi)) / dist2);
}

}  // namespace

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
    collectShadowEdges(scene_, params_, topology_, y.p, uint32_t(j), edges, weights, l.mesh);
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
    if (!shadowBorderPoint(scene_, params_, cam, lp.y, se, t, bp)) return;
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
