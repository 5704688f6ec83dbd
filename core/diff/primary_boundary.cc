#include "core/diff/primary_boundary.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/diff/film_projection.h"
#include "core/diff/gradient_options.h"
#include "core/math/sampling.h"

namespace invr {

namespace {

// An edge clipped to the near plane (3D end points a, b with camera depths) and to the film
// (the film-space fraction range [s0, s1] of the projected segment a -> b).
struct FilmEdge {
  uint32_t mesh;
  uint32_t face0, face1;  // MeshEdge::kNone for a boundary edge's missing face
  bool silhouette;        // seen from the eye (else a crease between two faces turned to it)
  Vec3 a, b;  // the edge's ends after clipping at the near plane
  uint32_t v0, v1;  // the mesh vertices it runs between (vertex parameters take the gradient)
  float za, zb;
  Vec2 fa, fb;  // film positions of a and b (unclipped to the film)
  float s0, s1;
  float length;  // film length of [s0, s1]
};

// Liang-Barsky: the parameter range of fa + s (fb - fa) inside [0, W] x [0, H].
bool clipToFilm(Vec2 fa, Vec2 fb, float W, float H, float& s0, float& s1) {
  s0 = 0.f;
  s1 = 1.f;
  const float d[2] = {fb.x - fa.x, fb.y - fa.y}, lo[2] = {0.f, 0.f}, hi[2] = {W, H}, p0[2] = {fa.x, fa.y};
  for (int k = 0; k < 2; ++k) {
    if (d[k] == 0.f) {
      if (p0[k] < lo[k] || p0[k] > hi[k]) return false;
      continue;
    }
    float t0 = (lo[k] - p0[k]) / d[k], t1 = (hi[k] - p0[k]) / d[k];
    if (t0 > t1) std::swap(t0, t1);
    s0 = std::max(s0, t0);
    s1 = std::min(s1, t1);
  }
  return s1 > s0;
}

// The film offset of the two side samples. They must straddle this edge and nothing else, and
// measure the radiance where the edge is. Next to a silhouette the faces turn edge-on and their
// film slivers get arbitrarily thin; a side stepping over one measured the next crease's jump too.
// And a side a fixed film offset off the edge lands, on a face seen edge-on, far from it in the
// world, where the radiance is not the edge's: on the knot, offsets starting at 1e-3 px with a
// floor of 1e-4 px read its derivative 0.7 % high. So the offset is set by how precisely the
// edge's point is known (`precision`: a few float roundings of it, in pixels) and shrinks tenfold
// until a side lands on each of a crease's two faces, or one on a silhouette's front face, down to
// `floor`.
double sideOffset(const Scene& scene, const Camera& cam, const FilmEdge& e, FilmPoint x, Vec2 n, double start, double floor,
                  SampleCounters& counters) {
  double eps = start;
  for (;;) {
    uint32_t face[2] = {MeshEdge::kNone, MeshEdge::kNone};
    for (int k = 0; k < 2; ++k) {
      const double sign = k == 0 ? -1.0 : 1.0;
      SurfaceHit h;
      ++counters.rays.camera;
      const Vec3 d = filmDirectionPrecise(cam, x.x + sign * eps * double(n.x), x.y + sign * eps * double(n.y), scene.width, scene.height);
      if (scene.intersect(cam.eye, d, h) && h.mesh == e.mesh && (h.tri == e.face0 || h.tri == e.face1))
        face[k] = h.tri;
    }
    const bool on0 = face[0] != MeshEdge::kNone, on1 = face[1] != MeshEdge::kNone;
    const bool straddles = e.silhouette ? on0 != on1 : on0 && on1 && face[0] != face[1];
    if (straddles || eps <= floor) return eps;
    eps *= 0.1;
  }
}

}  // namespace

float PrimaryBoundary::creaseJumpBound(Vec3 n0, Vec3 n1) { return std::clamp(length(n0 - n1), kMinCreaseWeight, 1.f); }

namespace {

// The largest cosine between the interpolated normal and the direction to light point q at the
// edge's ends and middle (0 if none faces it): the lit side's shading cosine along the edge, which
// scales its jump. Only a weight: it may be 0 where the edge's middle still faces q, so callers
// keep a floor.
float vertexCosineTowards(const TriangleMesh& mesh, const MeshEdge& e, Vec3 q) {
  const Vec3 p0 = mesh.positions[e.v0], p1 = mesh.positions[e.v1], n0 = mesh.normals[e.v0], n1 = mesh.normals[e.v1];
  float c = 0.f;
  for (const auto& [p, n] : {std::pair{p0, n0}, std::pair{p1, n1}, std::pair{(p0 + p1) * 0.5f, n0 + n1}}) {
    const float len = length(q - p) * length(n);
    if (len > 0.f) c = std::max(c, dot(n, q - p) / len);
  }
  return c;
}

// Points whose facing bounds an area light's: the facing of a face, sign(ng . (q - p)), is linear
// in q, so over the emitter's convex hull it takes the signs it takes at the hull's corners.
std::vector<Vec3> emitterCorners(const TriangleMesh& emitter) {
  if (emitter.positions.size() <= 8) return emitter.positions;
  Vec3 lo = emitter.positions[0], hi = lo;
  for (const Vec3& p : emitter.positions) {
    lo = Vec3(std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z));
    hi = Vec3(std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z));
  }
  std::vector<Vec3> c;
  for (int k = 0; k < 8; ++k) c.push_back(Vec3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z));
  return c;
}

// Per light of the scene: an area light's emitterCorners (empty for other lights).
std::vector<std::vector<Vec3>> lightCorners(const Scene& scene) {
  std::vector<std::vector<Vec3>> out(scene.lights.size());
  for (size_t k = 0; k < scene.lights.size(); ++k)
    if (scene.lights[k].kind == LightKind::Area) out[k] = emitterCorners(scene.meshes[scene.lights[k].mesh]);
  return out;
}

float terminatorBound(const Scene& scene, const std::vector<std::vector<Vec3>>& corners, uint32_t m, const MeshEdge& e,
                      const std::vector<Vec3>& normals) {
  constexpr float kMin = PrimaryBoundary::kMinCreaseWeight;
  const TriangleMesh& mesh = scene.meshes[m];
  if (e.boundary() || mesh.normals.empty()) return 0.f;
  const Vec3 n0 = normals[e.face0], n1 = normals[e.face1], p = mesh.positions[e.v0];  // p lies on both faces
  float bound = 0.f;
  for (size_t k = 0; k < scene.lights.size(); ++k) {
    const Light& l = scene.lights[k];
    switch (l.kind) {
      case LightKind::Point:
      case LightKind::Spot:
        if ((dot(n0, l.position - p) > 0.f) != (dot(n1, l.position - p) > 0.f))
          bound = std::max({bound, kMin, vertexCosineTowards(mesh, e, l.position)});
        break;
      case LightKind::Area: {
        bool all0 = true, none0 = true, all1 = true, none1 = true;
        float c = 0.f;
        for (const Vec3& q : corners[k]) {
          const bool f0 = dot(n0, q - p) > 0.f, f1 = dot(n1, q - p) > 0.f;
          all0 = all0 && f0, none0 = none0 && !f0, all1 = all1 && f1, none1 = none1 && !f1;
          c = std::max(c, vertexCosineTowards(mesh, e, q));
        }
        if (!((all0 && all1) || (none0 && none1))) bound = std::max({bound, kMin, c});
        break;
      }
      case LightKind::Environment:
      case LightKind::ConstantEnvironment:
        if (const float turn = length(n0 - n1); turn > 0.f) bound = std::max({bound, kMin, turn});
        break;
    }
  }
  return std::min(bound, 1.f);
}

// +1 if the faces of a closed, consistently wound mesh point out of it, -1 if they point in (the
// sign of its signed volume).
float outwardSign(const TriangleMesh& mesh) {
  double v = 0.0;
  for (size_t f = 0; f < mesh.triangleCount(); ++f) {
    const Vec3 a = mesh.positions[mesh.indices[3 * f]], b = mesh.positions[mesh.indices[3 * f + 1]], c = mesh.positions[mesh.indices[3 * f + 2]];
    v += double(dot(a, cross(b, c)));
  }
  return v < 0.0 ? -1.f : 1.f;
}

}  // namespace

float PrimaryBoundary::terminatorJumpBound(const Scene& scene, uint32_t m, const MeshEdge& e, const std::vector<Vec3>& normals) {
  return terminatorBound(scene, lightCorners(scene), m, e, normals);
}

std::vector<PrimaryBoundary::Candidate> PrimaryBoundary::candidates(int view, size_t* hiddenSkipped) const {
  const Camera& cam = scene_.cameras[size_t(view)];
  std::vector<Candidate> out;
  size_t hidden = 0;
  const std::vector<std::vector<Vec3>> corners = lightCorners(scene_);
  // A moving camera moves every mesh's edges on its film.
  std::vector<uint32_t> meshes = params_.movingMeshes();
  if (params_.movesCamera(view)) {
    meshes.resize(scene_.meshes.size());
    for (uint32_t m = 0; m < meshes.size(); ++m) meshes[m] = m;
  }
  for (uint32_t m : meshes) {
    if (m >= topology_.size()) continue;
    const TriangleMesh& mesh = scene_.meshes[m];
    const std::vector<Vec3>& normals = mesh.faceNormals;
    const std::vector<MeshEdge>& edges = topology_[m].edges();
    // A closed mesh seen from outside: a ray from the eye enters it before anything of it turned
    // away (outward normal facing away from the eye) can be hit, so an edge between two such
    // faces is never seen, and its samples would be spent on the visibility test that skips them.
    const bool seenFromOutside = topology_[m].closedOriented() && std::abs(meshWindingNumber(mesh, cam.eye)) < 0.5;
    const float outward = seenFromOutside ? outwardSign(mesh) : 0.f;
    auto towardsEye = [&](const MeshEdge& e, uint32_t f) { return outward * dot(normals[f], cam.eye - mesh.positions[e.v0]) > 0.f; };
    for (size_t i = 0; i < edges.size(); ++i) {
      const MeshEdge& e = edges[i];
      if (EdgeTopology::silhouetteFrom(e, mesh, normals, cam.eye)) {
        out.push_back({m, i, EdgeKind::Silhouette, 1.f});
        continue;
      }
      if (seenFromOutside && !towardsEye(e, e.face0) && !towardsEye(e, e.face1)) {
        hidden += e.crease || (terminators_ && terminatorBound(scene_, corners, m, e, normals) > 0.f);
        continue;
      }
      if (e.crease) {
        // Smooth meshes' creases (split normals) may jump by anything.
        out.push_back({m, i, EdgeKind::Crease, mesh.normals.empty() ? creaseJumpBound(normals[e.face0], normals[e.face1]) : 1.f});
      } else if (const float bound = terminators_ ? terminatorBound(scene_, corners, m, e, normals) : 0.f; bound > 0.f) {
        out.push_back({m, i, EdgeKind::Terminator, bound});
      }
    }
  }
  if (hiddenSkipped) *hiddenSkipped = hidden;
  return out;
}

PrimaryBoundary::PrimaryBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                                 const PrimaryBoundaryOptions& options)
    : scene_(scene),
      params_(params),
      topology_(topology),
      terminators_(options.terminators),
      sideOffsetRoundings_(options.sideOffsetRoundings),
      minSideOffsetRoundings_(options.minSideOffsetRoundings) {}

BoundaryPassStats PrimaryBoundary::run(const BoundaryView& bv) {
  const int view = bv.view, samples = bv.samples;
  const uint64_t stream = bv.stream, step = bv.step;
  const SamplerKind samplerKind = bv.sampler;
  const Image& adjoint = bv.adjoint;
  const InteriorEstimator& estimator = bv.estimator;
  const Camera& cam = scene_.cameras[size_t(view)];
  const int W = scene_.width, H = scene_.height;
  const float zNear = 1e-4f * scene_.radius;
  BoundaryPassStats st;
  // Candidates in the current pose: silhouettes from the eye, creases and terminators, clipped.
  std::vector<FilmEdge> edges;
  std::vector<float> lengths, weights, jumpBounds;
  size_t hidden = 0;
  for (const Candidate& cand : candidates(view, &hidden)) {
    const uint32_t m = cand.mesh;
    const TriangleMesh& mesh = scene_.meshes[m];
    const MeshEdge& e = topology_[m].edges()[cand.edge];
    FilmEdge fe;
    fe.mesh = m;
    fe.face0 = e.face0;
    fe.face1 = e.nonManifold ? MeshEdge::kNone : e.face1;
    fe.silhouette = cand.kind == EdgeKind::Silhouette;
    fe.a = mesh.positions[e.v0];
    fe.b = mesh.positions[e.v1];
    fe.v0 = e.v0;
    fe.v1 = e.v1;
    fe.za = dot(fe.a - cam.eye, cam.forward);
    fe.zb = dot(fe.b - cam.eye, cam.forward);
    if (fe.za < zNear && fe.zb < zNear) continue;
    if (fe.za < zNear || fe.zb < zNear) {  // clip at the near plane
      float t = (zNear - fe.za) / (fe.zb - fe.za);
      Vec3 c = fe.a + (fe.b - fe.a) * t;
      if (fe.za < zNear) { fe.a = c; fe.za = zNear; }
      else { fe.b = c; fe.zb = zNear; }
    }
    fe.fa = filmPosition(cam, fe.a, W, H);
    fe.fb = filmPosition(cam, fe.b, W, H);
    if (!clipToFilm(fe.fa, fe.fb, float(W), float(H), fe.s0, fe.s1)) continue;
    const Vec2 span = fe.fb - fe.fa;
    fe.length = std::sqrt(span.x * span.x + span.y * span.y) * (fe.s1 - fe.s0);
    if (!(fe.length > 0.f)) continue;
    terminatorEdges_ += cand.kind == EdgeKind::Terminator;
    edges.push_back(fe);
    lengths.push_back(fe.length);
    weights.push_back(fe.length * cand.jumpBound);
    jumpBounds.push_back(cand.jumpBound);
  }
  hiddenSkipped_ += hidden;
  st.candidateEdges = edges.size();
  for (float l : lengths) st.filmLength += double(l);
  if (edges.empty() || samples <= 0) return st;
  const Distribution1D pick(weights);
  double weightSum = 0;
  for (float w : weights) weightSum += double(w);
  const float total = float(weightSum);

  runBoundarySamples(samples, bv.scratch, bv.gradient, bv.cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    Sampler sampler = Sampler::forSampleSet(samplerKind, RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    float u = 0.f;
    const size_t picked = pick.sample(sampler.next1D(), &u);
    const FilmEdge& e = edges[picked];
    // A point uniform in film length on the clipped part, and the edge point P under it
    // (perspective-correct: 1/z and t/z are linear on the film); its sides are taken about P's
    // own film position.
    const float s = e.s0 + (e.s1 - e.s0) * u;
    const float t = s * e.za / ((1.f - s) * e.zb + s * e.za);
    const Vec3 P = e.a + (e.b - e.a) * t;
    // An edge point the camera does not see has no jump of its own, only what lies in front of it,
    // whose first-order change across 2 eps pixels of film, summed over the whole length of hidden
    // edges (most of a closed mesh's creases), biased the term by O(eps): +5 % on the knot at 1e-3
    // px. The segment stops short of P so the edge's own faces cannot occlude it.
    Vec3 toP;
    float distP;
    if (scene_.occludedSegment(cam.eye, cam.eye + (P - cam.eye) * (1.f - kVisibilitySlack), toP, distP)) return;
    Vec2 dir = e.fb - e.fa;
    dir = dir * (1.f / std::sqrt(dir.x * dir.x + dir.y * dir.y));
    const Vec2 n(-dir.y, dir.x);
    Vec3 dx, dy;
    filmJacobian(cam, P, H, dx, dy);
    // P's own rounding (half an ulp per coordinate, a few per operation) seen on the film.
    const double precision = std::ldexp(1.0, -23) * (1.0 + double(maxComponent(vmax(P, -P)))) * double(std::max(length(dx), length(dy)));
    const FilmPoint xp = filmPositionPrecise(cam, P, W, H);
    const double eps = sideOffset(scene_, cam, e, xp, n, sideOffsetRoundings_ * precision, minSideOffsetRoundings_ * precision, counters);
    const FilmCrossing c = radianceJump(scene_, estimator, cam, xp, n, eps, sampler, counters);
    const Rgb adj = adjoint.rgb(c.px, c.py);
    grad.setPixel(uint64_t(c.py) * uint64_t(W) + uint64_t(c.px));
    // 1 / pdf per unit film length: the sum of weights over the edge's jump bound.
    const float w = (adj.x * c.jump.x + adj.y * c.jump.y + adj.z * c.jump.z) * total / (jumpBounds[picked] * float(samples));
    if (w == 0.f) return;
    // Where P lies on the unclipped edge, for vertex parameters.
    const Vec3 A = scene_.meshes[e.mesh].positions[e.v0], AB = scene_.meshes[e.mesh].positions[e.v1] - A;
    const float tEdge = std::clamp(dot(P - A, AB) / dot(AB, AB), 0.f, 1.f);
    const Vec3 g = (dx * n.x + dy * n.y) * w;  // w * n . dfilm/dP
    params_.addEdgeGradient(scene_, e.mesh, e.v0, e.v1, tEdge, P, g, grad);
    params_.addCameraPointGradient(scene_, view, P, -g, grad);  // the camera moving moves P the other way on the film
  }, bv.pixels);
  return st;
}

void PrimaryBoundary::endStep(RayStats&, std::vector<std::pair<std::string, uint64_t>>& counters) {
  counters.emplace_back("terminator_edges", terminatorEdges_);
  counters.emplace_back("hidden_edges_skipped", hiddenSkipped_);
}

namespace {

const RegisterBoundaryTerm kPrimary({
    .name = PrimaryBoundaryOptions::kTerm,
    .order = 10,
    .pinnedStream = kPrimaryBoundaryStream,
    .applies = [](const Scene&, const GradientOptions& o) { return o.boundary.primary; },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> {
      return std::make_unique<PrimaryBoundary>(s.scene, s.params, s.topology, s.options.boundary.termOr<PrimaryBoundaryOptions>());
    },
    .describe =
        [](const BoundaryPlanInput& in) {
          std::string counts;
          if (in.params && !in.scene.cameras.empty()) {
            const std::vector<EdgeTopology> topology = buildBoundaryTopology(in.scene, *in.params);
            size_t hidden = 0, kinds[3] = {0, 0, 0};
            const PrimaryBoundary term(in.scene, *in.params, topology, in.options.boundary.termOr<PrimaryBoundaryOptions>());
            for (const PrimaryBoundary::Candidate& c : term.candidates(0, &hidden)) ++kinds[int(c.kind)];
            using Kind = PrimaryBoundary::EdgeKind;
            counts = "; in the scene as given, view 0 has " + std::to_string(kinds[int(Kind::Silhouette)]) + " silhouette, " +
                     std::to_string(kinds[int(Kind::Crease)]) + " crease and " + std::to_string(kinds[int(Kind::Terminator)]) +
                     " terminator candidate edges (before clipping to the film), and " + std::to_string(hidden) +
                     " hidden creases and terminators left out";
          }
          return "boundary, primary (Eq. 9-11): " + std::to_string(in.options.boundary.samplesFor(PrimaryBoundaryOptions::kTerm, in.scene.width, in.scene.height)) +
                 " edge samples per view and step on silhouette, crease and (smooth meshes) shadow-terminator edges of moving "
                 "meshes (of every mesh in a view whose camera moves), by clipped film length times a bound on the jump (creases between flat faces: |n0 - n1|; terminators: the "
                 "lit side's shading cosine), creases and terminators that a closed mesh seen from outside turns away from the eye "
                 "skipped (counted in the stats' hidden_edges_skipped), both sides with the same random numbers, hidden edge "
                 "points skipped; both sides traced with the interior estimator, a few float roundings of the edge point off it; box "
                 "pixel filter, so no pixel-boundary term" +
                 counts;
        },
    .memoryBytes = {},
    .samples = {Discontinuity::MeshEdges},
    .parse = [](const invr::v1::BoundarySpec& b) -> std::unique_ptr<BoundaryTermOptions> {
      if (!b.terms().has_primary()) return nullptr;
      const invr::v1::PrimaryBoundarySpec& spec = b.terms().primary();
      auto o = std::make_unique<PrimaryBoundaryOptions>();
      parseSharedTermFields(spec, PrimaryBoundaryOptions::kTerm, *o);
      if (spec.has_terminators()) o->terminators = spec.terminators();
      return o;
    },
});

}  // namespace

}  // namespace invr
