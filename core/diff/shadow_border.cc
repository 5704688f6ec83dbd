#include "core/diff/shadow_border.h"

#include <algorithm>
#include <cmath>

#include "core/diff/film_projection.h"
#include "core/diff/primary_boundary.h"
#include "core/math/sampling.h"
#include "core/render/direct_light.h"

namespace invr {

namespace {
float offsetAt(Vec3 p) { return 1e-4f * (1.f + maxComponent(vmax(p, -p))); }

// What `shade` makes of surface point `at` seen from the eye; black on an emitter (the border
// terms differentiate visibility of light, not of emitters).
template <class Shade>
Rgb shadeSurface(const Scene& scene, const SurfaceHit& at, Vec3 eye, Shade&& shade) {
  if (scene.meshLight[at.mesh] >= 0) return Rgb(0.f);
  const Vec3 wo = normalize(eye - at.p);
  const Bsdf bsdf = scene.materials[size_t(scene.meshMaterial[at.mesh])].at(at.uv);
  ShadingPoint sp{&at, &bsdf, shadingFrame(at, bsdf, wo), Vec3(), wo};
  sp.wo = sp.frame.toLocal(wo);
  return shade(sp);
}
}  // namespace

SurfaceHit receiverAt(const Scene& scene, const SurfaceHit& hit, Vec3 q) {
  const TriangleMesh& mesh = scene.meshes[hit.mesh];
  const Vec3 a = mesh.positions[mesh.indices[3 * size_t(hit.tri)]], e1 = mesh.positions[mesh.indices[3 * size_t(hit.tri) + 1]] - a,
             e2 = mesh.positions[mesh.indices[3 * size_t(hit.tri) + 2]] - a, d = q - a;
  const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2), r1 = dot(d, e1), r2 = dot(d, e2);
  const float det = d11 * d22 - d12 * d12;
  SurfaceHit at = det > 0.f ? scene.surfaceAt(hit.mesh, hit.tri, (d22 * r1 - d12 * r2) / det, (d11 * r2 - d12 * r1) / det) : hit;
  at.p = q;
  return at;
}

void collectShadowEdges(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology, ShadowSource source,
                        uint32_t sourceIndex, std::vector<ShadowEdge>& edges, std::vector<float>& weights, uint32_t skipMesh, int view) {
  const bool cameraMoves = params.movesCamera(view);
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    if (m == skipMesh || m >= topology.size() || topology[m].edges().empty()) continue;
    const TriangleMesh& mesh = scene.meshes[m];
    std::vector<Vec3> normals(mesh.triangleCount());
    for (uint32_t f = 0; f < normals.size(); ++f) normals[f] = scene.faceNormal(m, f);
    for (const MeshEdge& e : topology[m].edges()) {
      if (!EdgeTopology::silhouetteTowards(e, normals, source.from(mesh.positions[e.v0]))) continue;
      ShadowEdge se{sourceIndex, m, mesh.positions[e.v0], mesh.positions[e.v1], e.v0, e.v1};
      const float len = length(se.b - se.a);
      if (!(len > 0.f)) continue;
      const Vec3 mid = (se.a + se.b) * 0.5f, dir = -normalize(source.from(mid));
      SurfaceHit hit;
      const bool falls = scene.intersect(mid + dir * offsetAt(mid), dir, hit);
      const bool moving = cameraMoves || params.moves(m) || (falls && params.moves(hit.mesh));
      edges.push_back(se);
      weights.push_back(len * (falls ? 1.f : kUnlikelyShadowEdgeWeight) * (moving ? 1.f : kUnlikelyShadowEdgeWeight));
    }
  }
}

bool shadowBorderPoint(const Scene& scene, const ParameterRegistry& params, int view, ShadowSource source, const ShadowEdge& se, float t,
                       ShadowBorderPoint& bp, RayStats& rays) {
  const Camera& cam = scene.cameras[size_t(view)];
  const int W = scene.width, H = scene.height;
  bp.t = t;
  bp.e = se.a + (se.b - se.a) * t;
  bp.toE = -source.from(bp.e);
  const float distE = length(bp.toE);
  if (!(distE > 0.f)) return false;
  const Vec3 dir = bp.toE / distE;
  if (source.directional) bp.toE = dir;
  // Started just past the edge so the grazing faces of the edge itself are not hit.
  ++rays.shadow;
  if (!scene.intersect(bp.e + dir * offsetAt(bp.e), dir, bp.hit)) return false;
  if (!params.moves(se.mesh) && !params.moves(bp.hit.mesh) && !params.movesCamera(view)) return false;  // nothing here moves
  const Vec3 y = bp.hit.p, nr = bp.hit.ng;
  bp.denom = dot(nr, bp.toE);
  if (std::abs(bp.denom) < 1e-8f * distE) return false;  // grazing the receiver: measure zero
  // Where the renderer draws the border. Its shadow rays start an offset off the receiver on the
  // source's side (offsetOrigin) and end at the source (an area light's point lifted off its
  // emitter the same way): the drawn border is where the line from that end through e meets the
  // receiver's plane lifted by the offset, dropped back onto the plane, the offset times
  // cot(elevation of the source over the plane) from y. The pixel whose adjoint weighs the jump,
  // and the sides, are taken there: with y's pixel the estimate under a light 4 degrees above a
  // floor was 6 % low (y sat 0.03 px off the drawn border, and the adjoint changes sharply from
  // pixel to pixel at a moving border).
  const float lift = dot(nr, source.from(y)) >= 0.f ? offsetAt(y) : -offsetAt(y);
  Vec3 line = bp.toE;
  if (!source.directional && lengthSquared(source.n) > 0.f)
    line = bp.e - (source.v + source.n * (dot(source.n, y - source.v) >= 0.f ? offsetAt(source.v) : -offsetAt(source.v)));
  const float lineDenom = dot(nr, line);
  if (std::abs(lineDenom) < 1e-8f * length(line)) return false;
  const Vec3 drawn = bp.e + line * ((lift - dot(nr, bp.e - y)) / lineDenom) - nr * lift;
  bp.drawn = drawn;
  if (!(dot(drawn - cam.eye, cam.forward) > 0.f)) return false;
  bp.x = filmPosition(cam, drawn, W, H);
  if (!(bp.x.x >= 0.f && bp.x.y >= 0.f && bp.x.x < float(W) && bp.x.y < float(H))) return false;
  // A border the camera does not see is not in the image. Without this test the film sides of a
  // hidden border measured whatever lay in front of it, and where that was the occluder's own
  // silhouette (the source near the eye's line of sight) they counted the primary term's jump again.
  Vec3 toCam;
  float camDist;
  ++rays.shadow;
  if (scene.occludedSegment(offsetOrigin(drawn, nr, cam.eye - drawn), cam.eye, toCam, camDist)) return false;
  // The source lights y only from the side the camera sees it from; on the other side both sides
  // of the border are dark.
  if (!(dot(nr, source.from(y)) * dot(nr, cam.eye - y) > 0.f)) return false;
  bp.s = source.directional ? 1.f : length(y - source.v) / distE;
  // Film tangent of the curve: dy/dt = ds/dt (e - l) + s (b - a), ray-plane at y.
  const Vec3 de = se.b - se.a;
  const Vec3 dydt = bp.toE * (-bp.s * dot(nr, de) / bp.denom) + de * bp.s;
  filmJacobian(cam, drawn, H, bp.jx, bp.jy);
  const Vec2 dxdt(dot(bp.jx, dydt), dot(bp.jy, dydt));
  bp.speed = std::sqrt(dxdt.x * dxdt.x + dxdt.y * dxdt.y);
  if (!(bp.speed > 0.f)) return false;
  bp.n = Vec2(-dxdt.y / bp.speed, dxdt.x / bp.speed);
  // The two sides are points of the receiver's plane, 8 offsets off the drawn border along its
  // normal in that plane, oriented as the film normal n. Sides on the film (camera rays off x)
  // crossed the receiver's creases wherever the border ran within the side offset of one: on the
  // knot's 0.5 px facets the film sides of 59 % of samples landed on another facet than the
  // receiver's, +0.6 % of the derivative with shadows switched off, where the term must be 0.
  Vec3 m = cross(nr, dydt);
  const float mLen = length(m);
  if (!(mLen > 0.f)) return false;
  m = m / mLen;
  if (dot(bp.jx, m) * bp.n.x + dot(bp.jy, m) * bp.n.y < 0.f) m = -m;
  const float offset = 8.f * offsetAt(y);
  for (int k = 0; k < 2; ++k) bp.side[k] = receiverAt(scene, bp.hit, drawn + m * (k == 0 ? -offset : offset));
  return true;
}

void addShadowBorderGradient(const Scene& scene, const ParameterRegistry& params, int view, const ShadowEdge& se, const ShadowBorderPoint& bp,
                             double w, PathGradient& grad) {
  // dLoss/dtheta_k = w (n . J dy/dtheta_k), dy/dtheta_k = ds_k (e - l) + s de_k with
  // ds_k = (nr . u_k - s nr . de_k) / (nr . (e - l)); u_k, de_k the receiver's and the occluder's
  // velocities. With g = w J^T n and c = g . (e - l) / (nr . (e - l)):
  //   occluder: (s (g - c nr)) . de_k,   receiver: (c nr) . u_k.
  const Vec3 nr = bp.hit.ng;
  const Vec3 g = (bp.jx * bp.n.x + bp.jy * bp.n.y) * float(w);
  const float c = dot(g, bp.toE) / bp.denom;
  params.addEdgeGradient(scene, se.mesh, se.v0, se.v1, bp.t, bp.e, (g - nr * c) * bp.s, grad);
  params.addHitGradient(scene, bp.hit, nr * c, Vec3(0.f), grad);
  // The camera: the border stays where it is in the world and its film position x moves by
  // -J D_k(drawn) (parameters.h, addCameraPointGradient).
  params.addCameraPointGradient(scene, view, bp.drawn, -g, grad);
}

BoundaryPassStats sampleShadowBorders(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                                      int view, const Image& adjoint, int samples, const std::vector<BorderSource>& sources,
                                      const BorderSourceRadiance& radiance, uint64_t stream, uint64_t step, GradientScratchPool& scratch,
                                      std::vector<double>& gradient, const std::atomic<bool>* cancel, SamplerKind samplerKind,
                                      PixelDerivativeSink* pixels) {
  const Camera& cam = scene.cameras[size_t(view)];
  BoundaryPassStats st;
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
  for (uint32_t j = 0; j < sources.size(); ++j)
    if (sources[j].weight > 0.0) collectShadowEdges(scene, params, topology, sources[j].at, j, edges, weights, sources[j].skipMesh, view);
  st.candidateEdges = edges.size();
  if (edges.empty() || samples <= 0) return st;
  const Distribution1D pick(weights);

  runBoundarySamples(samples, scratch, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler = Sampler::forSampleSet(samplerKind, RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float t = 0.f;
    const size_t k = pick.sample(sampler.next1D(), &t);
    const ShadowEdge& se = edges[k];
    const BorderSource& src = sources[se.source];
    ShadowBorderPoint bp;
    if (!shadowBorderPoint(scene, params, view, src.at, se, t, bp, counters.rays)) return;
    const Rgb minus = radiance(se.source, bp.side[0], cam.eye, counters.rays);
    const Rgb plus = radiance(se.source, bp.side[1], cam.eye, counters.rays);
    const Rgb diff = minus - plus;
    if (isBlack(diff)) return;
    const int px = std::clamp(int(bp.x.x), 0, scene.width - 1), py = std::clamp(int(bp.x.y), 0, scene.height - 1);
    const Rgb adj = adjoint.rgb(px, py);
    grad.setPixel(uint64_t(py) * uint64_t(scene.width) + uint64_t(px));
    // pdf of (source, edge, t): the edge's probability (t is uniform on [0, 1]).
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(bp.speed) * src.weight / (double(pick.pmf(k)) * double(samples));
    if (w != 0.0) addShadowBorderGradient(scene, params, view, se, bp, w, grad);
  }, pixels);
  return st;
}

Rgb deltaSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const Light& l, RayStats& rays) {
  return shadeSurface(scene, at, eye, [&](const ShadingPoint& sp) {
    const LightSample ls = sampleLight(l, scene, sp.hit->p, Vec2(0.f, 0.f));
    if (isBlack(ls.radiance)) return Rgb(0.f);
    const Rgb f = bsdfTowards(sp, ls.wi);
    if (isBlack(f)) return Rgb(0.f);
    ++rays.shadow;
    return traceShadow(scene, sp, ls, nullptr) ? Rgb(0.f) : f * ls.radiance;
  });
}

Rgb directionalSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const LightSample& ls, RayStats& rays) {
  return shadeSurface(scene, at, eye, [&](const ShadingPoint& sp) {
    const Rgb f = bsdfTowards(sp, ls.wi);
    if (isBlack(f) || isBlack(ls.radiance)) return Rgb(0.f);
    ++rays.shadow;
    return scene.occludedDirection(Scene::shadowOrigin(sp.hit->p, sp.hit->ng, ls.wi), ls.wi) ? Rgb(0.f) : f * ls.radiance;
  });
}

float emittedPower(const Light& l) { return l.kind == LightKind::Area ? luminance(l.radiance) * l.scale * l.area : 0.f; }

Rgb pointSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const Light& l, const LightPoint& lp, RayStats& rays) {
  return shadeSurface(scene, at, eye, [&](const ShadingPoint& sp) {
    const Vec3 r = lp.y - sp.hit->p;
    const float dist2 = lengthSquared(r);
    if (!(dist2 > 0.f)) return Rgb(0.f);
    const Vec3 wi = r / std::sqrt(dist2);
    const Rgb f = bsdfTowards(sp, wi), Le = areaEmission(l, lp.n, -wi);
    if (isBlack(f) || isBlack(Le)) return Rgb(0.f);
    Vec3 dir;
    float tmax;
    ++rays.shadow;
    if (scene.occludedSegment(Scene::shadowOrigin(sp.hit->p, sp.hit->ng, wi), offsetOrigin(lp.y, lp.n, -wi), dir, tmax)) return Rgb(0.f);
    return f * Le * (std::abs(dot(lp.n, wi)) / dist2);
  });
}

}  // namespace invr
