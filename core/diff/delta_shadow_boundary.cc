#include "core/diff/delta_shadow_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/film_projection.h"
#include "core/math/sampling.h"

namespace invr {

namespace {

struct ShadowEdge {
  Vec3 light;  // the light's position
  uint32_t mesh;
  Vec3 a, b;
};

}  // namespace

DeltaShadowBoundary::DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

BoundaryPassStats DeltaShadowBoundary::run(const InteriorEstimator& estimator, int view, const Image& adjoint, int samples, uint64_t stream,
                                           uint64_t step, GradientScratchPool& scratchPool, std::vector<double>& gradient,
                                           const std::atomic<bool>* cancel) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  const int W = scene_.width, H = scene_.height;
  BoundaryPassStats st;
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
  for (const Light& light : scene_.lights) {
    if (!light.isDelta()) continue;
    for (uint32_t m = 0; m < scene_.meshes.size(); ++m) {
      if (m >= topology_.size() || topology_[m].edges().empty()) continue;
      const TriangleMesh& mesh = scene_.meshes[m];
      std::vector<Vec3> normals(mesh.triangleCount());
      for (uint32_t f = 0; f < normals.size(); ++f) normals[f] = scene_.faceNormal(m, f);
      for (const MeshEdge& e : topology_[m].edges()) {
        if (!EdgeTopology::silhouetteFrom(e, mesh, normals, light.position)) continue;
        ShadowEdge se{light.position, m, mesh.positions[e.v0], mesh.positions[e.v1]};
        float len = length(se.b - se.a);
        if (!(len > 0.f)) continue;
        edges.push_back(se);
        // Where the edge's shadow matters: it must fall on something, and the edge or that
        // receiver must move. One ray through the midpoint guesses both; edges failing the guess
        // keep a small weight (any positive weight is unbiased).
        const Vec3 mid = (se.a + se.b) * 0.5f, dir = normalize(mid - se.light);
        SurfaceHit hit;
        const bool falls = scene_.intersect(mid + dir * (1e-4f * (1.f + maxComponent(vmax(mid, -mid)))), dir, hit);
        const bool moving = params_.moves(m) || (falls && params_.moves(hit.mesh));
        weights.push_back(len * (falls ? 1.f : kUnlikelyEdgeWeight) * (moving ? 1.f : kUnlikelyEdgeWeight));
      }
    }
  }
  st.candidateEdges = edges.size();
  if (edges.empty() || samples <= 0) return st;
  const Distribution1D pick(weights);

  runBoundarySamples(samples, scratchPool, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler(RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float t = 0.f;
    const size_t k = pick.sample(sampler.next1D(), &t);
    const ShadowEdge& se = edges[k];
    // pdf of (edge, t): the edge's probability (t is uniform on [0, 1]).
    const double pdf = double(pick.pmf(k));
    const bool occluderMoves = params_.moves(se.mesh);
    const Vec3 e = se.a + (se.b - se.a) * t;
    const Vec3 toE = e - se.light;
    const float distE = length(toE);
    if (!(distE > 0.f)) return;
    const Vec3 dir = toE / distE;
    // The shadow point: the first surface beyond the edge (started just past it so the
    // grazing faces of the edge itself are not hit).
    SurfaceHit hit;
    const Vec3 start = e + dir * (1e-4f * (1.f + maxComponent(vmax(e, -e))));
    if (!scene_.intersect(start, dir, hit)) return;
    if (!occluderMoves && !params_.moves(hit.mesh)) return;  // nothing here moves
    const Vec3 y = hit.p, nr = hit.ng;
    const float denom = dot(nr, toE);
    if (std::abs(denom) < 1e-8f * distE) return;  // grazing the receiver: measure zero
    if (!(dot(y - cam.eye, cam.forward) > 0.f)) return;
    const Vec2 x = filmPosition(cam, y, W, H);
    if (!(x.x >= 0.f && x.y >= 0.f && x.x < float(W) && x.y < float(H))) return;
    const float s = length(y - se.light) / distE;
    // Film tangent of the curve: dy/dt = ds/dt (e - l) + s (b - a), ray-plane at y.
    const Vec3 de = se.b - se.a;
    const Vec3 dydt = toE * (-s * dot(nr, de) / denom) + de * s;
    Vec3 jx, jy;
    filmJacobian(cam, y, H, jx, jy);
    const Vec2 dxdt(dot(jx, dydt), dot(jy, dydt));
    const float speed = std::sqrt(dxdt.x * dxdt.x + dxdt.y * dxdt.y);
    if (!(speed > 0.f)) return;
    const Vec2 n(-dxdt.y / speed, dxdt.x / speed);
    // The sides must straddle the border the renderer draws, which its shadow rays' origin
    // offset (offsetOrigin) displaces by a few offsets: step that far, at least, on the film.
    const float offsetWorld = 8e-4f * (1.f + maxComponent(vmax(y, -y)));
    const float eps = std::max(PrimaryBoundary::kSideOffsetPixels, offsetWorld * std::max(length(jx), length(jy)));
    const FilmCrossing crossing = radianceJump(scene_, estimator, cam, x, n, eps, sampler, counters);
    const Rgb adj = adjoint.rgb(crossing.px, crossing.py), diff = crossing.jump;
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(speed) / (pdf * double(samples));
    if (w == 0.0) return;
    // dLoss/dtheta_k = w (n . J dy/dtheta_k), dy/dtheta_k = ds_k (e - l) + s de_k with
    // ds_k = (nr . u_k - s nr . de_k) / (nr . (e - l)); u_k, de_k the receiver's and the
    // occluder's velocities. With g = w J^T n: c = g . (e - l) / (nr . (e - l)),
    //   occluder: (s (g - c nr)) . de_k,   receiver: (c nr) . u_k.
    const Vec3 g = (jx * n.x + jy * n.y) * float(w);
    const float c = dot(g, toE) / denom;
    params_.addPointGradient(scene_, se.mesh, e, (g - nr * c) * s, grad);
    params_.addPointGradient(scene_, hit.mesh, y, nr * c, grad);
  });
  return st;
}

}  // namespace invr
