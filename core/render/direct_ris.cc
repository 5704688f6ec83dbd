#include "core/render/direct_light.h"

namespace invr {

// Candidates live in the union of the lights' native domains (light index x point, direction or
// nothing); the source density is pmf(light) * pdfNative and the target uses the same measure,
// so w = p_hat / p_c is well defined for delta, area and environment lights alike.
//
// The candidates are taken in batches of a shadow packet's width: each batch draws, selects and
// evaluates its candidates, traces their shadow rays as one packet, then streams them into the
// reservoir in order. Every draw's dimension is reserved in the order the one-by-one loop drew
// them, so the result is the one-by-one loop's number for number (up to a packet's rounding of a
// ray grazing an edge); draws nobody reads (a delta light's point, the pick of a candidate with
// zero weight) are never hashed.
Reservoir streamRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                    PathContext* ctx, LightSample& chosen, Rgb& chosenF, bool* nonFinite, DeltaLightCache* deltas) {
  DeltaLightCache local;
  if (!deltas) deltas = &local;
  Reservoir r;
  if (scene.lights.empty()) return r;
  constexpr int kBatch = ShadowPacket::kCapacity;
  constexpr int8_t kQueued = -2;  // a delta light's shadow ray is in the current packet
  struct Candidate {
    Candidate() {}  // written before read: a batch costs no initialisation
    union {
      LightSample ls;  // the candidate's own sample (unless a delta light's cached evaluation stands for it)
    };
    union {
      Rgb f;
    };
    DeltaLightCache::Entry* delta;
    uint64_t pickDim;
    float pmf, target;
    int ray;  // its shadow ray's slot in the packet (-1: none, or degenerate)
  };
  Candidate batch[kBatch];
  ShadowPacket packet;
  const Distribution1D& selection = scene.lightSelection();
  for (int first = 0; first < candidates; first += kBatch) {
    const int n = std::min(kBatch, candidates - first);
    packet.clear();
    for (int j = 0; j < n; ++j) {
      Candidate& c = batch[j];
      const float uSel = sampler.next1D();
      const uint64_t pointDim = sampler.reserve2D();
      c.pickDim = sampler.reserve1D();
      c.ray = -1;
      c.delta = nullptr;
      const size_t li = selection.sampleIndex(uSel);
      c.pmf = selection.pmf(li);
      if (!(c.pmf > 0.f)) {
        c.target = 0.f;
        continue;
      }
      const Light& light = scene.lights[li];
      c.delta = light.isDelta() ? deltas->at(scene, sp, uint32_t(li)) : nullptr;
      if (c.delta) {
        c.target = c.delta->target;
      } else {
        const Vec2 d2 = sampler.value2D(pointDim);
        c.ls = sampleLight(light, scene, sp.hit->p, Vec2(d2.y, d2.x), uint32_t(li));  // y drawn first: the independent streams' order
        c.target = risTarget(sp, c.ls, &c.f);
      }
      if (!std::isfinite(c.target)) {  // reported, not resampled: the caller drops the whole sample
        if (nonFinite) *nonFinite = true;
        c.target = 0.f;
      }
      if (!(c.target > 0.f) || !visibilityInTarget) continue;
      if (!c.delta) {
        c.ray = packet.push(sp, c.ls, ctx);
      } else if (c.delta->occluded == -1) {  // first ask: one ray for every candidate of this light
        c.ray = packet.push(sp, c.delta->ls, ctx);
        c.delta->occluded = kQueued;
      }
    }
    packet.trace(scene);
    for (int j = 0; j < n; ++j)  // the delta lights' answers first: later candidates of a light read them
      if (batch[j].delta && batch[j].delta->occluded == kQueued) batch[j].delta->occluded = packet.blocked(batch[j].ray) ? 1 : 0;
    int kept = -1;  // the batch's last kept candidate: copied out once, after the batch
    for (int j = 0; j < n; ++j) {
      const Candidate& c = batch[j];
      r.M += 1.f;
      if (!(c.pmf > 0.f)) continue;
      const LightSample& ls = c.delta ? c.delta->ls : c.ls;
      const bool blocked = visibilityInTarget && c.target > 0.f && (c.delta ? c.delta->occluded > 0 : packet.blocked(c.ray));
      const double w = c.target > 0.f && !blocked ? double(c.target) / (double(c.pmf) * double(ls.pdfNative)) : 0.0;
      if (!(w > 0.0)) continue;
      if (r.stream(ls.ref, w, c.target, sampler.value1D(c.pickDim))) kept = j;
    }
    if (kept >= 0) {
      const Candidate& c = batch[kept];
      chosen = c.delta ? c.delta->ls : c.ls;
      chosenF = c.delta ? c.delta->f : c.f;
    }
  }
  r.finalize(r.M);  // W = wSum / (M p_hat(y)); zero when no candidate had a positive target
  return r;
}

bool sampleDirectRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                     PathContext* ctx, DirectPath& out, Reservoir* reservoirOut) {
  LightSample chosen;
  Rgb chosenF(0.f);
  bool poisoned = false;
  Reservoir r = streamRis(scene, sp, sampler, candidates, visibilityInTarget, ctx, chosen, chosenF, &poisoned);
  if (reservoirOut) *reservoirOut = poisoned ? Reservoir() : r;
  if (poisoned) {
    out = nonFinitePath();
    return true;
  }
  if (!(r.W > 0.f)) return false;
  if (!visibilityInTarget && traceShadow(scene, sp, chosen, ctx)) return false;
  out = pathToLight(sp, chosen, chosenF, r.W);
  return true;
}

}  // namespace invr
