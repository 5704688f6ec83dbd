#include "core/restir/direct_restir.h"

#include <cmath>

#include "core/error.h"

namespace invr {

namespace {

// Target of light sample y at a stored reservoir's shading point (the support test of Alg. 3,
// line 9), in the geometry `pose` (null: the current one). Uses that point's own view direction:
// towards the eye of the camera that saw it (a primary hit lies on that camera's ray). Lights do
// not move (shape jobs refuse moving emitters), so y is where it was.
float targetAt(const Scene& scene, const StoredReservoir& q, const LightSampleRef& y, bool visibility, PathContext* ctx,
               const PoseSnapshot* pose = nullptr) {
  // visibility = false skips the shadow ray (used when V is already known to be 1).
  SurfaceHit h = pose ? scene.surfaceAt(*pose, q.mesh, q.tri, q.b1, q.b2) : scene.surfaceAt(q.mesh, q.tri, q.b1, q.b2);
  Bsdf b = scene.materials[size_t(scene.meshMaterial[h.mesh])].at(h.uv);
  const Vec3 wo = normalize(scene.cameras[q.view].eye - h.p);
  ShadingPoint sp{&h, &b, shadingFrame(h, b, wo), Vec3(), wo};
  sp.wo = sp.frame.toLocal(wo);
  LightSample ls = evalLightSample(scene, y, h.p);
  float t = risTarget(sp, ls);
  if (t > 0.f && visibility) {
    if (!pose) {
      if (traceShadow(scene, sp, ls, ctx)) t = 0.f;
    } else {
      // traceShadow's ray, traced through the geometry of `pose`.
      if (ctx && ctx->stats) ++ctx->stats->shadow;
      Vec3 o = Scene::shadowOrigin(h.p, h.ng, ls.wi);
      bool blocked;
      if (std::isinf(ls.dist))
        blocked = scene.occludedDirection(*pose, o, ls.wi);
      else
        blocked = scene.occludedSegment(*pose, o, isBlack(ls.lightNormal) ? ls.lightPoint : offsetOrigin(ls.lightPoint, ls.lightNormal, -ls.wi));
      if (blocked) t = 0.f;
    }
  }
  return t;
}

}  // namespace

// Combination rule: Alg. 3 with the Z normalisation (Bitterli et al. 2020, Alg. 6). Each input j
// (the fresh reservoir and every reused one) enters with weight p_hat(y_j; here) W_j M_j, and the
// result is normalised by Z = sum of M_j over the inputs that could have produced the chosen y
// (p_hat(y; p_j) > 0). Because the M_j act as fixed confidence weights normalised over the inputs
// whose support contains y, the result is unbiased for any M_j, so capping M (the M-cap) changes
// variance, never the mean. We chose Z over generalised-RIS MIS weights because it needs one
// target evaluation per neighbour for the chosen sample only (k + 1 instead of (k + 1)^2). The
// support test must ask whether the neighbour's own target was positive at y, in the geometry the
// neighbour was created in (§3.2): where its sample came from. What the neighbour recorded answers
// that without evaluating anything where it is enough (below); otherwise the target is evaluated
// in that geometry (shape jobs keep the poses of the moving meshes per step, ReservoirStore::poseOf)
// or, with the paper's multi-view shortcut, in the current one (biased while geometry moves).
// Material and light parameters bounded away from zero do not change the support.
bool sampleDirectRestir(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, const RestirSettings& s,
                        const ReservoirStore* prev, PathContext* ctx, DirectPath& out, Reservoir& combined,
                        RestirCounters* counters, const NeighbourHints* hints, uint8_t* deltaKnown, uint8_t* deltaVisible) {
  LightSample chosen;
  Rgb chosenF(0.f);
  bool poisoned = false;
  DeltaLightCache deltas;  // delta lights evaluated (and traced) from sp, shared with the neighbours
  Reservoir fresh = streamRis(scene, sp, sampler, s.candidates, s.visibilityInTarget, ctx, chosen, chosenF, &poisoned, &deltas);

  constexpr int kMaxNeighbours = 32;
  uint32_t nb[kMaxNeighbours];
  float nbM[kMaxNeighbours];
  int k = (prev && !prev->empty())
              ? prev->neighbours(sp.hit->p, sp.hit->ns, std::min(s.neighbours, kMaxNeighbours), s.radius, s.normalDot, nb, hints)
              : 0;

  for (int i = 0; i < k; ++i) INVR_INVARIANT(nb[i] < prev->size(), "a neighbour index past the stored reservoirs");
  Reservoir c;
  c.M = fresh.M;
  int chosenFrom = -1;  // -1: the fresh reservoir; i: neighbour i
  // The picks' draws are reserved in order and hashed only for inputs with a positive weight
  // (Sampler::reserve1D): the same numbers as drawing each one.
  const uint64_t freshPick = sampler.reserve1D();
  if (fresh.W > 0.f && fresh.wSum > 0.0) c.stream(fresh.y, fresh.wSum, fresh.targetY, sampler.value1D(freshPick));
  for (int i = 0; i < k; ++i) {
    const StoredReservoir& q = prev->items()[nb[i]];
    const uint64_t pick = sampler.reserve1D();
    nbM[i] = std::min(q.r.M, s.mCap);
    c.M += nbM[i];
    if (!(q.r.W > 0.f)) continue;
    DeltaLightCache::Entry* e = scene.lights[q.r.y.light].isDelta() ? deltas.at(scene, sp, q.r.y.light) : nullptr;
    // Initialised from the call (not assigned after): no copy of the whole sample.
    const LightSample reused = e ? LightSample() : evalLightSample(scene, q.r.y, sp.hit->p);
    Rgb reusedF(0.f);
    float t = e ? e->target : risTarget(sp, reused, &reusedF);
    if (!std::isfinite(t)) {
      poisoned = true;
      t = 0.f;
    }
    if (t > 0.f && s.visibilityInTarget &&
        (e ? DeltaLightCache::occluded(*e, scene, sp, ctx) : traceShadow(scene, sp, reused, ctx)))
      t = 0.f;
    const double w = double(t) * double(q.r.W) * double(nbM[i]);
    if (w > 0.0 && c.stream(q.r.y, w, t, sampler.value1D(pick))) {
      chosen = e ? e->ls : reused;
      chosenF = e ? e->f : reusedF;
      chosenFrom = i;
    }
  }
  float Z = 0.f;
  if (c.targetY > 0.f) {
    Z = fresh.M;  // fresh candidates come from light sampling here: they cover every y with target > 0
    // What a neighbour's point knew when it was created answers its support test without
    // re-evaluating the target there (surface, texture, BSDF, light, shadow ray):
    // - its own sample had a positive target there, visibility included (W > 0);
    // - a delta light it traced had a positive target there (rays are traced only for those), and
    //   the ray says whether it was visible.
    // Both describe the geometry it was created in, which is the exact test. The multi-view
    // shortcut tests in the current geometry instead, so it takes them only while nothing moved.
    const bool created = s.supportInCreatedGeometry;
    const bool recordedHolds = created || scene.geometryVersion() == 0;
    const uint32_t yBit = c.y.light < 8 && scene.lights[c.y.light].isDelta() ? 1u << c.y.light : 0u;
    for (int i = 0; i < k; ++i) {
      const StoredReservoir& q = prev->items()[nb[i]];
      if (recordedHolds && i == chosenFrom) {
        Z += nbM[i];
        continue;
      }
      if (recordedHolds && (q.deltaKnown & yBit)) {
        if (q.deltaVisible & yBit) Z += nbM[i];
        continue;
      }
      const PoseSnapshot* pose = created ? prev->poseOf(q) : nullptr;
      if (pose && pose->version == scene.geometryVersion()) pose = nullptr;  // created in this geometry
      if (targetAt(scene, q, c.y, s.visibilityInTarget, ctx, pose) > 0.f) Z += nbM[i];
    }
  }
  c.finalize(Z);
  if (deltaKnown && deltaVisible) deltas.bits(*deltaKnown, *deltaVisible);
  if (poisoned) {  // counted and dropped by the caller; nothing non-finite is kept for reuse
    combined = Reservoir();
    if (counters) ++counters->shadingPoints;
    out = nonFinitePath();
    return true;
  }
  combined = c;
  if (counters) {
    counters->neighboursUsed += uint64_t(k);
    counters->shadingPoints += 1;
    counters->sumM += c.M;
  }
  if (!(c.W > 0.f)) return false;
  if (!s.visibilityInTarget && traceShadow(scene, sp, chosen, ctx)) return false;
  out = pathToLight(sp, chosen, chosenF, c.W);
  return true;
}

}  // namespace invr
