#include "core/render/direct_light.h"

namespace invr {

// Candidates live in the union of the lights' domains (light index x point or direction); the
// source density is pmf(light) * pdf(sample) in that light's own measure and the target uses
// the same measure, so w = p_hat / p_c is well defined for delta and area lights alike.
Rgb estimateDirectRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates,
                      bool visibilityInTarget, PathContext* ctx) {
  if (scene.lights.empty() || candidates <= 0) return Rgb(0.f);
  double wSum = 0.0;
  LightSample chosen;
  Rgb chosenF(0.f);
  float chosenTarget = 0.f;
  for (int m = 0; m < candidates; ++m) {
    float uSel = sampler.next1D();
    Vec2 u2(sampler.next1D(), sampler.next1D());
    float uPick = sampler.next1D();
    size_t li = scene.lightSelection().sample(uSel);
    float pmf = scene.lightSelection().pmf(li);
    if (!(pmf > 0.f)) continue;
    LightSample ls = sampleLight(scene.lights[li], scene, sp.hit->p, u2);
    Rgb f = unshadowedContribution(sp, ls);
    float target = luminance(f);
    if (target > 0.f && visibilityInTarget && traceShadow(scene, sp, ls, ctx)) target = 0.f;
    if (!(target > 0.f)) continue;
    double w = double(target) / (double(pmf) * double(ls.pdf));
    wSum += w;
    if (double(uPick) * wSum < w) {  // replace with probability w / wSum
      chosen = ls;
      chosenF = f;
      chosenTarget = target;
    }
  }
  // W = 0 whenever no candidate had a positive target.
  if (!(wSum > 0.0) || !(chosenTarget > 0.f)) return Rgb(0.f);
  float W = float(wSum / (double(candidates) * double(chosenTarget)));
  if (!visibilityInTarget && traceShadow(scene, sp, chosen, ctx)) return Rgb(0.f);
  return chosenF * W;
}

}  // namespace invr
