// An independent forward path tracer, for tests only: NEE + MIS (or RIS) at every vertex and
// Russian roulette, written as one loop without the shared walk (core/render/path_walk.h) that
// the renderer and every gradient estimator use. Tests that compare the walk's radiance with
// something other than itself use it (path_walk_test.cc); finite-difference references use the
// renderer, because they check derivatives against the primal, which the walk computes once for both.
#pragma once

#include "core/render/direct_light.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace invr::test {

inline Rgb referencePathRadiance(const Scene& scene, Vec3 o, Vec3 d, Sampler& sampler, const RenderOptions& opt) {
  Rgb L(0.f), beta(1.f);
  bool specular = true;
  float prevBsdfPdf = 0.f;
  Vec3 prevP = o;
  const bool mis = opt.estimator == LightEstimator::NeeMis;
  const auto& select = scene.lightSelection();
  for (int depth = 0;; ++depth) {
    SurfaceHit hit;
    if (!scene.intersect(o, d, hit)) {
      for (uint32_t li : scene.infiniteLights()) {
        const Light& l = scene.lights[li];
        Rgb Le = environmentRadiance(l, d);
        if (specular) L += beta * Le;
        else if (mis) L += beta * Le * powerHeuristic(prevBsdfPdf, select.pmf(li) * environmentPdf(l, d));
      }
      break;
    }
    if (int li = scene.meshLight[hit.mesh]; li >= 0) {
      const Light& l = scene.lights[size_t(li)];
      Rgb Le = areaEmission(l, hit.ng, -d);
      if (!isBlack(Le)) {
        if (specular) L += beta * Le;
        else if (mis) L += beta * Le * powerHeuristic(prevBsdfPdf, select.pmf(size_t(li)) * areaLightPdf(l, prevP, hit.p, hit.ng));
      }
    }
    if (depth >= opt.maxDepth) break;
    Bsdf bsdf = scene.materials[size_t(scene.meshMaterial[hit.mesh])].at(hit.uv);
    ShadingPoint sp{&hit, &bsdf, Frame(hit.ns), Vec3(), -d};
    sp.wo = sp.frame.toLocal(-d);
    if (!bsdf.isDelta())
      L += beta * (mis ? estimateDirectNeeMis(scene, sp, sampler, nullptr)
                       : estimateDirectRis(scene, sp, sampler, opt.risCandidates, opt.risVisibilityInTarget, nullptr));
    if (depth + 1 >= opt.maxDepth && !mis && !bsdf.isDelta()) break;
    float uc = sampler.next1D();
    Vec2 u(sampler.next1D(), sampler.next1D());
    auto bs = bsdf.sample(sp.wo, uc, u);
    if (!bs) break;
    Vec3 wi = sp.frame.toWorld(bs->wi);
    float side = dot(wi, hit.ng) * dot(-d, hit.ng);
    if (bs->transmitted ? side >= 0.f : side <= 0.f) break;
    beta *= bs->weight;
    specular = bs->delta;
    prevBsdfPdf = bs->pdf;
    prevP = hit.p;
    o = offsetOrigin(hit.p, hit.ng, wi);
    d = wi;
    if (depth + 1 >= opt.russianRouletteDepth) {
      float q = std::min(1.f, maxComponent(beta));
      if (!(sampler.next1D() < q)) break;
      beta = beta / q;
    }
  }
  return L;
}

}  // namespace invr::test
