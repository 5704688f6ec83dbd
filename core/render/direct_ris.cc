#include "core/render/direct_light.h"

namespace invr {

// Candidates live in the union of the lights' native domains (light index x point, direction or
// nothing); the source density is pmf(light) * pdfNative and the target uses the same measure,
// so w = p_hat / p_c is well defined for delta, area and environment lights alike.
Reservoir streamRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                    PathContext* ctx, LightSample& chosen, Rgb& chosenF, bool* nonFinite, DeltaLightCache* deltas) {
  DeltaLightCache local;
  if (!deltas) deltas = &local;
  Reservoir r;
  if (scene.lights.empty()) return r;
  LightSample fresh;  // the candidate, unless a delta light's cached evaluation stands for it
  Rgb freshF(0.f);
  for (int m = 0; m < candidates; ++m) {
    float uSel = sampler.next1D();
    const Vec2 d2 = sampler.next2D();
    const Vec2 u2(d2.y, d2.x);  // y drawn first: the independent streams' order before 2D draws
    float uPick = sampler.next1D();
    size_t li = scene.lightSelection().sample(uSel);
    float pmf = scene.lightSelection().pmf(li);
    if (!(pmf > 0.f)) { r.M += 1.f; continue; }
    const Light& light = scene.lights[li];
    DeltaLightCache::Entry* e = light.isDelta() ? deltas->at(scene, sp, uint32_t(li)) : nullptr;
    float target;
    if (e) {
      target = e->target;
    } else {
      fresh = sampleLight(light, scene, sp.hit->p, u2, uint32_t(li));
      target = risTarget(sp, fresh, &freshF);
    }
    const LightSample& ls = e ? e->ls : fresh;
    if (!std::isfinite(target)) {  // reported, not resampled: the caller drops the whole sample
      if (nonFinite) *nonFinite = true;
      target = 0.f;
    }
    if (target > 0.f && visibilityInTarget && (e ? DeltaLightCache::occluded(*e, scene, sp, ctx) : traceShadow(scene, sp, ls, ctx)))
      target = 0.f;
    double w = target > 0.f ? double(target) / (double(pmf) * double(ls.pdfNative)) : 0.0;
    if (r.update(ls.ref, w, target, uPick)) {
      chosen = ls;
      chosenF = e ? e->f : freshF;
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
