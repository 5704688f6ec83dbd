#include "core/diff/primary_boundary.h"

#include <algorithm>
#include <cmath>

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

// The film offset of the two side samples. They must straddle this edge and nothing else. Next to
// a silhouette the faces turn edge-on and their film slivers get arbitrarily thin; a side stepping
// over one measured the next crease's jump too, a bias that grew with the offset (the knot's
// gradient moved 5 % between 1e-4 and 1e-3 px). So the offset shrinks tenfold until a side lands
// on each of a crease's two faces, or one on a silhouette's front face, down to kMinSideOffsetPixels.
float sideOffset(const Scene& scene, const Camera& cam, const FilmEdge& e, Vec2 x, Vec2 n, SampleCounters& counters) {
  float eps = PrimaryBoundary::kSideOffsetPixels;
  for (;;) {
    uint32_t face[2] = {MeshEdge::kNone, MeshEdge::kNone};
    for (int k = 0; k < 2; ++k) {
      const float sign = k == 0 ? -1.f : 1.f;
      SurfaceHit h;
      ++counters.rays.camera;
      if (scene.intersect(cam.eye, cam.direction(x.x + sign * eps * n.x, x.y + sign * eps * n.y, scene.width, scene.height), h) &&
          h.mesh == e.mesh && (h.tri == e.face0 || h.tri == e.face1))
        face[k] = h.tri;
    }
    const bool on0 = face[0] != MeshEdge::kNone, on1 = face[1] != MeshEdge::kNone;
    const bool straddles = e.silhouette ? on0 != on1 : on0 && on1 && face[0] != face[1];
    if (straddles || eps <= PrimaryBoundary::kMinSideOffsetPixels) return eps;
    eps *= 0.1f;
  }
}

}  // namespace

float PrimaryBoundary::creaseJumpBound(Vec3 n0, Vec3 n1) { return std::clamp(length(n0 - n1), kMinCreaseWeight, 1.f); }

PrimaryBoundary::PrimaryBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

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
  // Candidates in the current pose: silhouettes from the eye and creases, clipped.
  std::vector<FilmEdge> edges;
  std::vector<float> lengths, weights, jumpBounds;
  for (uint32_t m : params_.movingMeshes()) {
    const TriangleMesh& mesh = scene_.meshes[m];
    std::vector<Vec3> normals(mesh.triangleCount());
    for (uint32_t f = 0; f < normals.size(); ++f) normals[f] = scene_.faceNormal(m, f);
    for (const MeshEdge& e : topology_[m].edges()) {
      if (!e.crease && !EdgeTopology::silhouetteFrom(e, mesh, normals, cam.eye)) continue;
      FilmEdge fe;
      fe.mesh = m;
      fe.face0 = e.face0;
      fe.face1 = e.nonManifold ? MeshEdge::kNone : e.face1;
      fe.silhouette = EdgeTopology::silhouetteFrom(e, mesh, normals, cam.eye);
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
      const bool flatCrease = !fe.silhouette && fe.face1 != MeshEdge::kNone && mesh.normals.empty();
      const float bound = flatCrease ? creaseJumpBound(normals[fe.face0], normals[fe.face1]) : 1.f;
      edges.push_back(fe);
      lengths.push_back(fe.length);
      weights.push_back(fe.length * bound);
      jumpBounds.push_back(bound);
    }
  }
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
    // A point uniform in film length on the clipped part, and the edge point under it
    // (perspective-correct: 1/z and t/z are linear on the film).
    const float s = e.s0 + (e.s1 - e.s0) * u;
    const Vec2 x = e.fa + (e.fb - e.fa) * s;
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
    const FilmCrossing c = radianceJump(scene_, estimator, cam, x, n, sideOffset(scene_, cam, e, x, n, counters), sampler, counters);
    const Rgb adj = adjoint.rgb(c.px, c.py);
    // 1 / pdf per unit film length: the sum of weights over the edge's jump bound.
    const float w = (adj.x * c.jump.x + adj.y * c.jump.y + adj.z * c.jump.z) * total / (jumpBounds[picked] * float(samples));
    if (w == 0.f) return;
    Vec3 dx, dy;
    filmJacobian(cam, P, H, dx, dy);
    // Where P lies on the unclipped edge, for vertex parameters.
    const Vec3 A = scene_.meshes[e.mesh].positions[e.v0], AB = scene_.meshes[e.mesh].positions[e.v1] - A;
    const float tEdge = std::clamp(dot(P - A, AB) / dot(AB, AB), 0.f, 1.f);
    params_.addEdgeGradient(scene_, e.mesh, e.v0, e.v1, tEdge, P, (dx * n.x + dy * n.y) * w, grad);  // w * n . dfilm/dP
  });
  return st;
}

namespace {

const RegisterBoundaryTerm kPrimary({
    .name = "primary",
    .order = 10,
    .stream = kPrimaryBoundaryStream,
    .applies = [](const Scene&, const GradientOptions& o) { return o.boundary.primary; },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> { return std::make_unique<PrimaryBoundary>(s.scene, s.params, s.topology); },
    .describe =
        [](const BoundaryPlanInput& in) {
          return "boundary, primary (Eq. 9-11): " + std::to_string(in.options.boundary.samplesFor(in.scene.width, in.scene.height)) +
                 " edge samples per view and step on silhouette and crease edges of moving meshes, by clipped film length times a "
                 "bound on the jump (creases between flat faces: |n0 - n1|), both sides with the same random numbers, hidden edge "
                 "points skipped; both sides traced with the interior estimator; box pixel filter, so no pixel-boundary term";
        },
    .memoryBytes = {},
});

}  // namespace

}  // namespace invr
