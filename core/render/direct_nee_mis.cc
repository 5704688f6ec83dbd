#include "core/render/direct_light.h"

namespace invr {

bool sampleDirectNee(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx, DirectPath& out,
                     const float* lightPmf, int* chosen) {
  if (scene.lights.empty()) return false;
  float uSel = sampler.next1D();
  const Vec2 d2 = sampler.next2D();
  const Vec2 u2(d2.y, d2.x);  // y drawn first: the independent streams' order before 2D draws
  size_t li = lightPmf ? sampleSmallPmf(lightPmf, scene.lights.size(), uSel) : scene.lightSelection().sample(uSel);
  float pmf = lightPmf ? lightPmf[li] : scene.lightSelection().pmf(li);
  if (chosen) *chosen = int(li);
  if (!(pmf > 0.f)) return false;
  LightSample ls = sampleLight(scene.lights[li], scene, sp.hit->p, u2, uint32_t(li));
  if (!(ls.pdf > 0.f) || isBlack(ls.radiance)) return false;
  Rgb f = bsdfTowards(sp, ls.wi);
  if (isBlack(f)) return false;
  if (traceShadow(scene, sp, ls, ctx)) return false;
  float lightPdf = pmf * ls.pdf;
  float w = ls.delta ? 1.f : powerHeuristic(lightPdf, sp.bsdf->pdf(sp.wo, sp.frame.toLocal(ls.wi)));
  // In solid angle: weight = w / lightPdf; pathToLight multiplies by the jacobian, so divide here.
  out = pathToLight(sp, ls, f, w / (pmf * ls.pdfNative));
  out.mis = w;
  out.misWeighted = !ls.delta;
  return true;
}

}  // namespace invr
