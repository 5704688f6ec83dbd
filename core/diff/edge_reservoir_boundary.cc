#include "core/diff/edge_reservoir_boundary.h"

#include <algorithm>
#include <cmath>

#include "core/diff/area_shadow_boundary.h"
#include "core/diff/film_projection.h"
#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"

namespace invr {

namespace {

float rayOffset(Vec3 p) { return 1e-4f * (1.f + maxComponent(vmax(p, -p))); }

// The support of the target: the edge is a silhouette from y and y's light emits towards p^B.
// Made from p^B and face normals alone, so a reused reservoir answers it where it was created.
bool inSupport(const Light& l, Vec3 y, Vec3 ny, Vec3 pB, Vec3 nA, Vec3 nB, bool single) {
  const Vec3 toY = y - pB;
  if (!single && (dot(nA, toY) > 0.f) == (dot(nB, toY) > 0.f)) return false;
  return !isBlack(areaEmission(l, ny, -toY));
}

struct LightBox {
  uint32_t mesh = 0;
  Vec3 corner[8];
};

LightBox lightBox(const Light& l, const TriangleMesh& mesh) {
  LightBox b;
  b.mesh = l.mesh;
  Vec3 lo(INFINITY), hi(-INFINITY);
  for (const Vec3& p : mesh.positions) {
    lo = vmin(lo, p);
    hi = vmax(hi, p);
  }
  for (int i = 0; i < 8; ++i) b.corner[i] = Vec3((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
  return b;
}

// Whether the edge (v0, v1) with face normals nA, nB can be a silhouette from some point y of the
// box (inSupport's test, with p^B on the edge). n·(y - p) is linear in y and in p, so its range over
// the box and the edge is its range over the corners and the two ends. The edge is never a
// silhouette when both faces face every y, or neither does; the margin (welded copies of the ends
// differ by the weld tolerance, and rounding) keeps the test conservative.
bool maySilhouette(Vec3 nA, Vec3 nB, Vec3 v0, Vec3 v1, const LightBox& box) {
  float aMin = INFINITY, aMax = -INFINITY, bMin = INFINITY, bMax = -INFINITY, scale = 0.f;
  for (const Vec3& v : {v0, v1})
    for (const Vec3& c : box.corner) {
      const Vec3 d = c - v;
      const float a = dot(nA, d), b = dot(nB, d);
      aMin = std::min(aMin, a);
      aMax = std::max(aMax, a);
      bMin = std::min(bMin, b);
      bMax = std::max(bMax, b);
      scale = std::max({scale, maxComponent(vmax(d, -d)), maxComponent(vmax(v, -v))});
    }
  const float margin = 1e-4f * scale;
  const bool allFacing = aMin > margin && bMin > margin, noneFacing = aMax < -margin && bMax < -margin;
  return !(allFacing || noneFacing);
}

struct Candidate {
  uint32_t light = 0, tri = 0;
  float b0 = 0.f, b1 = 0.f;
  Vec3 y, n;
};

}  // namespace

bool EdgeReservoirBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (emittedPower(l) > 0.f) return true;
  return false;
}

EdgeReservoirBoundary::EdgeReservoirBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                                             EdgeReservoirSet& previous, const EdgeSamplingSettings& settings)
    : scene_(scene), params_(params), topology_(topology), previous_(previous), settings_(settings) {
  settings_.candidates = std::max(1, settings_.candidates);
  std::vector<float> power(scene.lights.size());
  for (size_t i = 0; i < power.size(); ++i) power[i] = emittedPower(scene.lights[i]);
  if (!power.empty() && *std::max_element(power.begin(), power.end()) > 0.f) pickLight_ = Distribution1D(power);

  // The emitting lights' bounding boxes, for the silhouette culling below.
  std::vector<LightBox> boxes;
  for (const Light& l : scene.lights)
    if (l.kind == LightKind::Area && emittedPower(l) > 0.f && l.mesh < scene.meshes.size()) boxes.push_back(lightBox(l, scene.meshes[l.mesh]));

  std::vector<float> base;
  firstEdge_.assign(topology.size() + 1, 0);
  for (uint32_t m = 0; m < topology.size() && m < scene.meshes.size(); ++m) {
    firstEdge_[m] = uint32_t(edges_.size());
    const TriangleMesh& mesh = scene.meshes[m];
    const std::vector<MeshEdge>& list = topology[m].edges();
    for (uint32_t e = 0; e < list.size(); ++e) {
      const float len = length(mesh.positions[list[e].v1] - mesh.positions[list[e].v0]);
      edges_.push_back({m, e});
      // An edge no light point sees as a silhouette holds no shadow border: its target is zero
      // for every light sample, so leaving it out of p_k changes no expectation.
      const MeshEdge& me = list[e];
      bool border = false;
      for (size_t b = 0; b < boxes.size() && !border; ++b)
        border = boxes[b].mesh != m && (me.boundary() || maySilhouette(scene.faceNormal(m, me.face0), scene.faceNormal(m, me.face1),
                                                                        mesh.positions[me.v0], mesh.positions[me.v1], boxes[b]));
      border = border && std::isfinite(len) && len > 0.f;
      if (border) ++candidateEdges_;
      base.push_back(border ? len * (params.moves(m) || params.hasCameraParameters() ? 1.f : kUnlikelyShadowEdgeWeight) : 0.f);
    }
  }
  for (size_t m = std::min(topology.size(), scene.meshes.size()); m < firstEdge_.size(); ++m) firstEdge_[m] = uint32_t(edges_.size());

  // Re-place the previous reservoirs on their edges (the index wants where they are now). Without
  // neighbours to merge nothing searches it, and edge importance needs only their edges.
  std::vector<Vec3> where;
  if (settings_.reuse && settings_.neighbours > 0) {
    where.resize(previous.items.size());
    for (size_t i = 0; i < where.size(); ++i) {
      const EdgeReservoir& r = previous.items[i];
      const MeshEdge& e = topology[r.mesh].edges()[r.edge];
      const Vec3 a = scene.meshes[r.mesh].positions[e.v0], b = scene.meshes[r.mesh].positions[e.v1];
      where[i] = a + (b - a) * r.t;
    }
  }
  previous.index(std::move(where));
  const Vec3 diag = scene.boundsMax - scene.boundsMin;
  radius_ = kNeighbourRadius * length(diag);

  if (settings_.reuse && settings_.edgeImportance && !previous.items.empty()) {
    std::vector<double> sum(edges_.size(), 0.0);
    std::vector<uint32_t> count(edges_.size(), 0);
    double total = 0.0;
    for (const EdgeReservoir& r : previous.items) {
      const double mean = r.M > 0.f ? r.wSum / double(r.M) : 0.0;
      const size_t k = firstEdge_[r.mesh] + r.edge;
      sum[k] += mean;
      ++count[k];
      total += mean;
    }
    // Most edges of a detailed mesh hold no reservoir or one: each edge's mean starts from the
    // mean over all edges as one prior reservoir, so an edge no sample visited last step is not
    // starved, and one sample with nothing behind it halves its edge's weight instead of zeroing it.
    const double mean = total / double(previous.items.size());
    const double eps = double(kEdgeImportanceFloor) * mean;
    if (eps > 0.0)
      for (size_t k = 0; k < base.size(); ++k) base[k] = float(double(base[k]) * ((sum[k] + mean) / (count[k] + 1.0) + eps));
  }
  if (!base.empty() && *std::max_element(base.begin(), base.end()) > 0.f) pickEdge_ = Distribution1D(base);
}

BoundaryPassStats EdgeReservoirBoundary::run(int view, const Image& adjoint, int samples, uint64_t stream, uint64_t step,
                                             GradientScratchPool& scratchPool, std::vector<double>& gradient,
                                             std::vector<EdgeReservoir>& created, const std::atomic<bool>* cancel,
                                             PixelDerivativeSink* pixels) const {
  BoundaryPassStats st;
  if (samples <= 0 || pickEdge_.size() == 0 || pickLight_.size() == 0) return st;
  st.candidateEdges = candidateEdges_;
  const Camera& cam = scene_.cameras[size_t(view)];
  const int W = scene_.width, H = scene_.height;
  // The target's floor c: a tenth of what a border of typical film speed (5 % of the film's size
  // per unit t) over a pixel of mean |dL/dI| would give.
  double meanAdj = 0.0;
  std::vector<float> absAdj(size_t(W) * size_t(H));
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Rgb a = adjoint.rgb(x, y);
      absAdj[size_t(y) * size_t(W) + size_t(x)] = std::abs(a.x) + std::abs(a.y) + std::abs(a.z);
      meanAdj += double(absAdj[size_t(y) * size_t(W) + size_t(x)]);
    }
  meanAdj /= double(W) * double(H);
  // The target reads |dL/dI| averaged over the pixels within kAdjointRadius: one pixel's value is
  // mostly the noise of the step's render, which a reused sample chosen for it would carry into
  // the next step's (other) noise.
  std::vector<float> smoothAdj(absAdj.size());
  {
    const int R = kAdjointRadius;
    std::vector<float> rows(absAdj.size());
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float s = 0.f;
        int n = 0;
        for (int dx = std::max(0, x - R); dx <= std::min(W - 1, x + R); ++dx, ++n) s += absAdj[size_t(y) * size_t(W) + size_t(dx)];
        rows[size_t(y) * size_t(W) + size_t(x)] = s / float(n);
      }
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        float s = 0.f;
        int n = 0;
        for (int dy = std::max(0, y - R); dy <= std::min(H - 1, y + R); ++dy, ++n) s += rows[size_t(dy) * size_t(W) + size_t(x)];
        smoothAdj[size_t(y) * size_t(W) + size_t(x)] = s / float(n);
      }
  }
  const float floorC = float(0.1 * meanAdj * 0.05 * double(W + H));
  if (!(floorC > 0.f)) return st;  // dL/dI is zero: so is this term
  const size_t base = created.size();
  created.resize(base + size_t(samples));
  const float maxM = settings_.maxM * float(settings_.candidates);

  runBoundarySamples(samples, scratchPool, gradient, cancel, st, [&](int i, SampleCounters& counters, PathGradient& grad) {
    // Independent whatever the job's sampler: these samples become edge reservoirs that later
    // steps resample together, which needs independent inputs (InteriorEstimator::stratifiable).
    Sampler sampler(RngKey{stream, step, uint64_t(view), uint64_t(i), 0});
    EdgeReservoir& r = created[base + size_t(i)];
    float t = 0.f;
    const size_t k = pickEdge_.sample(sampler.next1D(), &t);
    const EdgeRef ref = edges_[k];
    const MeshEdge& e = topology_[ref.mesh].edges()[ref.edge];
    const TriangleMesh& mesh = scene_.meshes[ref.mesh];
    const ShadowEdge se{0, ref.mesh, mesh.positions[e.v0], mesh.positions[e.v1], e.v0, e.v1};
    r.mesh = ref.mesh;
    r.edge = ref.edge;
    r.t = t;
    r.pB = se.a + (se.b - se.a) * t;
    r.single = e.boundary();
    r.nA = scene_.faceNormal(ref.mesh, e.face0);
    r.nB = r.single ? r.nA : scene_.faceNormal(ref.mesh, e.face1);

    // p̂(y) = g(y) (c + h(y)) for this sample's p^B (see the header).
    auto target = [&](const Candidate& c) -> float {
      const Light& l = scene_.lights[c.light];
      if (l.mesh == ref.mesh || !inSupport(l, c.y, c.n, r.pB, r.nA, r.nB, r.single)) return 0.f;
      const Vec3 toB = r.pB - c.y;
      const float d2 = lengthSquared(toB);
      if (!(d2 > 0.f)) return 0.f;
      const float g = luminance(areaEmission(l, c.n, toB)) * std::abs(dot(c.n, toB)) / (d2 * std::sqrt(d2));
      ShadowBorderPoint bp;
      float h = 0.f;
      if (shadowBorderPoint(scene_, params_, view, ShadowSource::at(c.y, c.n), se, t, bp, counters.rays)) {
        const float a = smoothAdj[size_t(std::clamp(int(bp.x.y), 0, H - 1)) * size_t(W) + size_t(std::clamp(int(bp.x.x), 0, W - 1))];
        const Vec3 toY = c.y - bp.hit.p;
        const float r2 = lengthSquared(toY);
        if (r2 > 0.f)
          h = a * bp.speed * std::abs(dot(bp.hit.ng, toY)) / std::sqrt(r2) * (d2 / r2);
        // A light point hidden from the edge casts no border there. Only h sees it, so the
        // support stays g's; the target then prefers light points the edge sees (an area light
        // mostly behind a board would otherwise take its share of the picks for nothing).
        if (h > 0.f) {
          Vec3 dir;
          float tmax;
          ++counters.rays.shadow;
          const Vec3 from = r.pB + normalize(c.y - r.pB) * rayOffset(r.pB);
          if (scene_.occludedSegment(from, Scene::shadowOrigin(c.y, c.n, r.pB - c.y), dir, tmax)) h = 0.f;
        }
      }
      const float p = g * (floorC + (std::isfinite(h) ? h : 0.f));
      return std::isfinite(p) ? p : 0.f;
    };

    Reservoir res;  // only its streaming: y is tracked in `chosen`
    Candidate chosen;
    for (int j = 0; j < settings_.candidates; ++j) {
      Candidate c;
      c.light = uint32_t(pickLight_.sample(sampler.next1D()));
      const Light& l = scene_.lights[c.light];
      float remapped;
      const Vec2 uv = sampler.next2D();
      const float u = uv.x, v = uv.y;
      c.tri = uint32_t(l.triangles.sample(u, &remapped));
      const Vec2 bc = sampleUniformTriangle({remapped, v});
      c.b0 = bc.x;
      c.b1 = bc.y;
      const SurfaceHit yh = scene_.surfaceAt(l.mesh, c.tri, c.b0, c.b1);
      c.y = yh.p;
      c.n = yh.ng;
      const float p = target(c);
      const double pdf = double(pickLight_.pmf(c.light)) / double(l.area);
      if (res.update(LightSampleRef{}, p > 0.f ? double(p) / pdf : 0.0, p, sampler.next1D())) chosen = c;
    }
    float Z = res.M;
    uint32_t nb[8];
    const int found = settings_.reuse ? previous_.nearest(r.pB, radius_, settings_.neighbours, nb) : 0;
    const EdgeReservoir* used[8];
    float usedM[8];
    for (int q = 0; q < found; ++q) {
      const EdgeReservoir& o = previous_.items[nb[q]];
      used[q] = &o;
      usedM[q] = std::min(o.M, maxM);
      const float u = sampler.next1D();
      if (!(o.W > 0.f)) continue;
      Candidate c;
      c.light = o.light;
      c.tri = o.tri;
      c.b0 = o.b0;
      c.b1 = o.b1;
      const SurfaceHit yh = scene_.surfaceAt(scene_.lights[o.light].mesh, o.tri, o.b0, o.b1);
      c.y = yh.p;
      c.n = yh.ng;
      const float p = target(c);
      if (res.stream(LightSampleRef{}, double(p) * double(o.W) * double(usedM[q]), p, u)) chosen = c;
    }
    for (int q = 0; q < found; ++q) res.M += usedM[q];
    if (res.targetY > 0.f) {
      // 1/Z (Alg. 3): the reservoirs whose target could have produced y, each tested where it was made.
      const Light& l = scene_.lights[chosen.light];
      for (int q = 0; q < found; ++q)
        if (l.mesh != used[q]->mesh && inSupport(l, chosen.y, chosen.n, used[q]->pB, used[q]->nA, used[q]->nB, used[q]->single))
          Z += usedM[q];
    }
    res.finalize(Z);
    r.wSum = res.wSum;
    r.M = res.M;
    r.W = res.W;
    if (!(res.W > 0.f)) return;
    r.light = chosen.light;
    r.tri = chosen.tri;
    r.b0 = chosen.b0;
    r.b1 = chosen.b1;

    // The sample: F(p^B, y) W / p(p^B), F measured on the film (Eq. 25).
    ShadowBorderPoint bp;
    const bool onFilm = shadowBorderPoint(scene_, params_, view, ShadowSource::at(chosen.y, chosen.n), se, t, bp, counters.rays);
    const Vec3 dir = normalize(r.pB - chosen.y);
    if (onFilm) {
      r.hasP1 = true;
      r.p1 = bp.hit.p;
    } else {
      SurfaceHit hit;
      ++counters.rays.shadow;
      if (scene_.intersect(r.pB + dir * rayOffset(r.pB), dir, hit)) {
        r.hasP1 = true;
        r.p1 = hit.p;
      }
      return;
    }
    const Light& l = scene_.lights[chosen.light];
    const LightPoint lp{chosen.light, chosen.y, chosen.n, 0.0};
    const Rgb minus = pointSourceRadiance(scene_, bp.side[0], cam.eye, l, lp, counters.rays);
    const Rgb plus = pointSourceRadiance(scene_, bp.side[1], cam.eye, l, lp, counters.rays);
    const Rgb diff = minus - plus;
    if (isBlack(diff)) return;
    const int px = std::clamp(int(bp.x.x), 0, W - 1), py = std::clamp(int(bp.x.y), 0, H - 1);
    const Rgb adj = adjoint.rgb(px, py);
    grad.setPixel(uint64_t(py) * uint64_t(W) + uint64_t(px));
    const double w = double(adj.x * diff.x + adj.y * diff.y + adj.z * diff.z) * double(bp.speed) * double(res.W) /
                     (double(pickEdge_.pmf(k)) * double(samples));
    if (w != 0.0) addShadowBorderGradient(scene_, params_, view, se, bp, w, grad);
  }, pixels);
  return st;
}

size_t EdgeReservoirBoundary::preserve(const std::vector<int>& views, std::vector<EdgeReservoir>& next, RayStats& rays) const {
  size_t kept = 0;
  for (const EdgeReservoir& r : previous_.items) {
    if (!r.hasP1 || r.age + 1 >= kMaxAge) continue;
    bool seen = false;
    for (int v : views) {
      const Camera& cam = scene_.cameras[size_t(v)];
      if (!(dot(r.p1 - cam.eye, cam.forward) > 0.f)) continue;
      const Vec2 x = filmPosition(cam, r.p1, scene_.width, scene_.height);
      if (!(x.x >= 0.f && x.y >= 0.f && x.x < float(scene_.width) && x.y < float(scene_.height))) continue;
      const Vec3 toEye = cam.eye - r.p1;
      const float dist = length(toEye);
      const Vec3 d = toEye / dist;
      Vec3 dir;
      float tmax;
      ++rays.shadow;
      if (!scene_.occludedSegment(r.p1 + d * rayOffset(r.p1), cam.eye, dir, tmax)) {
        seen = true;
        break;
      }
    }
    if (seen) continue;
    next.push_back(r);
    ++next.back().age;
    ++kept;
  }
  return kept;
}

const EdgeReservoirSet* keptEdgeReservoirs(const BoundaryStateSlots& session) {
  auto it = session.find(kEdgeFirstAreaShadowsName);
  return it == session.end() || !it->second ? nullptr : &static_cast<const EdgeReservoirState&>(*it->second).edges;
}

namespace {

// The term as the engine runs it: a step's sampler over the session's reservoirs, collecting this
// step's reservoirs view by view; with reuse they replace the session's at the end of the step,
// with the previous ones no view of the batch sees (Alg. 8).
class EdgeFirstAreaShadows final : public BoundaryTerm {
 public:
  EdgeFirstAreaShadows(const BoundaryStep& s, const EdgeSamplingSettings& settings)
      : sampler_(s.scene, s.params, s.topology, boundaryState<EdgeReservoirState>(s.state).edges, settings),
        store_(boundaryState<EdgeReservoirState>(s.state).edges),
        views_(s.views),
        keep_(settings.reuse), preserve_(settings.reuse && s.options.preserveOccluded && !s.allSessionViews) {}
  BoundaryPassStats run(const BoundaryView& v) override {
    return sampler_.run(v.view, v.adjoint, v.samples, v.stream, v.step, v.scratch, v.gradient, created_, v.cancel, v.pixels);
  }
  void endStep(RayStats& rays, std::vector<std::pair<std::string, uint64_t>>& counters) override {
    if (!keep_) return;
    // Alg. 8: the previous step's reservoirs whose p1 no view of this batch sees stay, unless the
    // batch holds every view the session serves (then no later step could want them more).
    const size_t preserved = preserve_ ? sampler_.preserve(views_, created_, rays) : 0;
    store_.items = std::move(created_);
    store_.index({});
    counters.emplace_back("edge_reservoirs", store_.items.size());
    counters.emplace_back("edge_reservoirs_preserved", preserved);
  }

 private:
  EdgeReservoirBoundary sampler_;
  EdgeReservoirSet& store_;
  std::vector<int> views_;
  bool keep_, preserve_;
  std::vector<EdgeReservoir> created_;
};

EdgeSamplingSettings edgeSettings(const GradientOptions& o) {
  const bool reuse = o.method == GradientMethod::Restir && !o.forwardOnly;
  EdgeSamplingSettings es;
  es.candidates = o.method == GradientMethod::Pt ? 1 : o.restir.candidates;
  es.reuse = reuse;
  const EdgeFirstAreaShadowOptions& own = o.boundary.termOr<EdgeFirstAreaShadowOptions>();
  es.edgeImportance = reuse && own.edgeImportance;
  es.neighbours = own.edgeNeighbours;
  return es;
}

const RegisterBoundaryTerm kEdgeFirst({
    .name = kEdgeFirstAreaShadowsName,
    .order = 30,
    .pinnedStream = kAreaShadowBoundaryStream,
    .applies =
        [](const Scene& scene, const GradientOptions& o) {
          return o.boundary.secondary && o.boundary.areaSampling == BoundaryOptions::AreaSampling::EdgeFirst && EdgeReservoirBoundary::applies(scene);
        },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> { return std::make_unique<EdgeFirstAreaShadows>(s, edgeSettings(s.options)); },
    .describe =
        [](const BoundaryPlanInput& in) {
          const GradientOptions& g = in.options;
          const BoundaryOptions& b = g.boundary;
          const EdgeSamplingSettings es = edgeSettings(g);
          const bool reuse = es.reuse;
          const std::string light = g.method == GradientMethod::Pt ? std::string("one light sample")
                                                                   : "streaming RIS over " + std::to_string(g.restir.candidates) + " light samples";
          return "boundary, secondary, area lights (multi-directional, Eq. 21-26): " +
                 std::to_string(b.samplesFor(kEdgeFirstAreaShadowsName, in.scene.width, in.scene.height)) +
                 " samples per view and step, an edge point first, then the light point by " + light +
                 (reuse ? std::string("; an edge reservoir kept per sample (Alg. 6; Alg. 8 keeps those no view of the batch sees)") +
                              (es.neighbours > 0 ? ", each sample merging " + std::to_string(es.neighbours) +
                                                          " kd-tree neighbour(s) among the previous step's"
                                                    : std::string()) +
                              (es.edgeImportance ? "; edges drawn by edge importance (Eq. 27)" : "; edges by length")
                        : std::string("; edges by length")) +
                 "; jump evaluated directly";
        },
    // One reservoir per sample and view of a shard, this step's and the previous step's with its
    // kd-tree, Alg. 8 survivors at most kMaxAge steps old.
    .memoryBytes =
        [](const BoundaryPlanInput& in) {
          if (!edgeSettings(in.options).reuse) return 0.0;
          return double(in.shardViews) * double(in.options.boundary.samplesFor(kEdgeFirstAreaShadowsName, in.scene.width, in.scene.height)) *
                 double(sizeof(EdgeReservoir) + 24) * (in.options.preserveOccluded ? 2.0 + 1.0 : 2.0);
        },
    .samples = {Discontinuity::AreaLightShadows},
    // The shared edge_importance and edge_neighbours are this term's, kept as job-wide aliases; its
    // own message's fields override them.
    .parse = [](const invr::v1::BoundarySpec& b) -> std::unique_ptr<BoundaryTermOptions> {
      const bool own = b.terms().has_area_shadows_edge_first();
      if (!own && !b.has_edge_importance() && b.edge_neighbours() == 0) return nullptr;
      const invr::v1::EdgeFirstAreaShadowSpec& spec = b.terms().area_shadows_edge_first();
      auto o = std::make_unique<EdgeFirstAreaShadowOptions>();
      parseSharedTermFields(spec, kEdgeFirstAreaShadowsName, *o);
      if (b.has_edge_importance()) o->edgeImportance = b.edge_importance();
      if (spec.has_edge_importance()) o->edgeImportance = spec.edge_importance();
      if (b.edge_neighbours() < 0 || b.edge_neighbours() > 8)
        throw InputError("optimization.boundary.edge_neighbours: must be in 0..8 (0, the default: none)");
      o->edgeNeighbours = b.edge_neighbours();
      if (spec.has_edge_neighbours()) {
        if (spec.edge_neighbours() < 0 || spec.edge_neighbours() > 8)
          throw InputError("optimization.boundary.terms.area_shadows_edge_first.edge_neighbours: must be in 0..8 (0, the default: none)");
        o->edgeNeighbours = spec.edge_neighbours();
      }
      return o;
    },
});

}  // namespace

}  // namespace invr
