#include "core/render/path_tracer.h"

#include "core/render/direct_light.h"

namespace invr {

Rgb pathRadiance(const Scene& scene, Vec3 o, Vec3 d, Sampler& sampler, const RenderOptions& opt, PathContext* ctx) {
  Rgb L(0.f), beta(1.f);
  bool specular = true;   // previous vertex was the camera or a delta lobe: emission is not covered by NEE
  float prevBsdfPdf = 0.f;
  Vec3 prevP = o;
  const bool mis = opt.estimator == LightEstimator::NeeMis;
  const auto& select = scene.lightSelection();

  for (int depth = 0;; ++depth) {
    if (ctx && ctx->stats) ++(depth == 0 ? ctx->stats->camera : ctx->stats->bounce);
    if (ctx && ctx->record) ctx->record->push_back({o, d, std::numeric_limits<float>::infinity(), false});
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
    if (!bsdf.isDelta()) {
      L += beta * (mis ? estimateDirectNeeMis(scene, sp, sampler, ctx)
                       : estimateDirectRis(scene, sp, sampler, opt.risCandidates, opt.risVisibilityInTarget, ctx));
    }
    // At the last vertex the continuation ray only adds emission: needed for the BSDF half of
    // MIS and after delta lobes; with RIS, NEE alone covers emission seen through rough lobes.
    if (depth + 1 >= opt.maxDepth && !mis && !bsdf.isDelta()) break;

    float uc = sampler.next1D();
    Vec2 u(sampler.next1D(), sampler.next1D());
    auto bs = bsdf.sample(sp.wo, uc, u);
    if (!bs) break;
    Vec3 wi = sp.frame.toWorld(bs->wi);
    // Shading normals can send a reflection below the geometric surface (or the reverse): drop it.
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

}  // namespace invr
