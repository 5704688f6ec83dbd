#include "core/render/direct_light.h"

namespace invr {

// Candidates live in the union of the lights' native domains (light index x point, direction or
// nothing); the source density is pmf(light) * pdfNative and the target uses the same measure,
// so w = p_hat / p_c is well defined for delta, area and environment lights alike.
//
// Which light each candidate samples. With few lights and candidates (the zoo's scenes), the
// number of candidates of each light is drawn at once: a multinomial over the selection pmf,
// drawn as one binomial per light but the last (one random number per light, not one per
// candidate). A delta light's candidates are all the same sample (one point, one shadow ray), so
// its k candidates enter the reservoir as one of k times the weight: the reservoir's M, wSum and
// chosen sample have the distribution the one-by-one stream (Alg. 1) gives them, for two random
// numbers per light where the stream took two per candidate. Otherwise each candidate selects its
// light with a random number of its own, in the one-by-one order.
//
// The candidates are taken in batches of a shadow packet's width: each batch draws and evaluates
// its candidates, traces their shadow rays as one packet, then streams them into the reservoir in
// order. Every draw's dimension is reserved in the order a one-by-one loop over the same
// candidates draws them, so the result is that loop's number for number (up to a packet's
// rounding of a ray grazing an edge); draws nobody reads (a delta light's point, the pick of a
// candidate with zero weight) are never hashed.
namespace {

// Candidate counts per light are drawn when the scene has at most this many lights and the
// candidates are at most kCountedCandidates (sampleBinomial's tails stay representable).
constexpr size_t kCountedLights = 8;
constexpr int kCountedCandidates = 64;

// The candidates' lights, group by group: (light, how many candidates the group stands for).
class CandidateLights {
 public:
  CandidateLights(const Distribution1D& selection, const Scene& scene, int candidates, Sampler& sampler)
      : selection_(selection), scene_(scene), left_(candidates),
        counted_(selection.size() <= kCountedLights && candidates <= kCountedCandidates) {
    if (!counted_) return;
    const size_t n = selection.size();
    double rest = 0;  // the pmf mass of lights i.. (summed from the back: exact zeros stay zero)
    double suffix[kCountedLights + 1];
    suffix[n] = 0;
    for (size_t i = n; i-- > 0;) suffix[i] = rest += double(selection.pmf(i));
    int remaining = candidates;
    for (size_t i = 0; i < n; ++i) {
      if (i + 1 == n || suffix[i + 1] <= 0.0) {  // the last light with mass takes the rest
        counts_[i] = remaining;
        for (size_t k = i + 1; k < n; ++k) counts_[k] = 0;
        break;
      }
      counts_[i] = sampleBinomial(remaining, double(selection.pmf(i)) / suffix[i], sampler.next1D());
      remaining -= counts_[i];
    }
  }
  bool done() const { return left_ == 0; }
  // The next group: one candidate, or a delta light's every candidate.
  void next(Sampler& sampler, size_t& light, int& count) {
    if (!counted_) {
      light = selection_.sampleIndex(sampler.next1D());
      count = 1;
      --left_;
      return;
    }
    while (counts_[light_] == 0) ++light_;
    light = light_;
    count = scene_.lights[light_].isDelta() ? counts_[light_] : 1;
    counts_[light_] -= count;
    left_ -= count;
  }
  // Whether a delta light's candidate draws a (never read) point, as the one-by-one stream does.
  bool drawsDeltaPoints() const { return !counted_; }

 private:
  const Distribution1D& selection_;
  const Scene& scene_;
  int left_;
  bool counted_;
  size_t light_ = 0;
  int counts_[kCountedLights];
};

}  // namespace

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
    int count;  // candidates it stands for
    int ray;    // its shadow ray's slot in the packet (-1: none, or degenerate)
  };
  Candidate batch[kBatch];
  ShadowPacket packet;
  const Distribution1D& selection = scene.lightSelection();
  CandidateLights lights(selection, scene, candidates, sampler);
  while (!lights.done()) {
    int n = 0;
    packet.clear();
    for (; n < kBatch && !lights.done(); ++n) {
      Candidate& c = batch[n];
      size_t li;
      lights.next(sampler, li, c.count);
      const Light& light = scene.lights[li];
      const bool delta = light.isDelta();
      const uint64_t pointDim = !delta || lights.drawsDeltaPoints() ? sampler.reserve2D() : 0;
      c.pickDim = sampler.reserve1D();
      c.ray = -1;
      c.delta = nullptr;
      c.pmf = selection.pmf(li);
      if (!(c.pmf > 0.f)) {
        c.target = 0.f;
        continue;
      }
      c.delta = delta ? deltas->at(scene, sp, uint32_t(li)) : nullptr;
      if (c.delta) {
        c.target = c.delta->target;
      } else {
        const Vec2 d2 = delta ? Vec2(0.f, 0.f) : sampler.value2D(pointDim);  // a delta light's point does not depend on it
        // Constructed in place (the union member has no object yet): assigning would build the
        // sample (88 bytes) on the stack and copy it, a store-forwarding stall measured at 7 % of
        // streamRis on cornell RIS.
        ::new (&c.ls) LightSample(sampleLight(light, scene, sp.hit->p, Vec2(d2.y, d2.x), uint32_t(li)));  // y drawn first: the independent streams' order
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
      r.M += float(c.count);
      if (!(c.pmf > 0.f)) continue;
      const LightSample& ls = c.delta ? c.delta->ls : c.ls;
      const bool blocked = visibilityInTarget && c.target > 0.f && (c.delta ? c.delta->occluded > 0 : packet.blocked(c.ray));
      const double w = c.target > 0.f && !blocked ? double(c.count) * double(c.target) / (double(c.pmf) * double(ls.pdfNative)) : 0.0;
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
