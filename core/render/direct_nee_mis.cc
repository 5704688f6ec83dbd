#include "core/render/direct_light.h"

namespace invr {

Rgb estimateDirectNeeMis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx) {
  if (scene.lights.empty()) return Rgb(0.f);
  float uSel = sampler.next1D();
  Vec2 u2(sampler.next1D(), sampler.next1D());
  size_t li = scene.lightSelection().sample(uSel);
  float pmf = scene.lightSelection().pmf(li);
  if (!(pmf > 0.f)) return Rgb(0.f);
  LightSample ls = sampleLight(scene.lights[li], scene, sp.hit->p, u2);
  Rgb c = unshadowedContribution(sp, ls);
  if (isBlack(c)) return Rgb(0.f);
  if (traceShadow(scene, sp, ls, ctx)) return Rgb(0.f);
  float lightPdf = pmf * ls.pdf;
  float w = ls.delta ? 1.f : powerHeuristic(lightPdf, sp.bsdf->pdf(sp.wo, sp.frame.toLocal(ls.wi)));
  return c * (w / lightPdf);
}

}  // namespace invr
