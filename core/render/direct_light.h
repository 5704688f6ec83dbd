// Direct-illumination estimators at one surface vertex. Each returns an estimate of
//   sum over lights of  integral f(wo, wi) |cos| Le(wi) V(wi) dwi
// (without the path throughput). One estimator per file.
#pragma once

#include "core/math/rng.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace invr {

struct ShadingPoint {
  const SurfaceHit* hit;
  const Bsdf* bsdf;
  Frame frame;  // shading frame
  Vec3 wo;      // local
  Vec3 woWorld;
};

inline float powerHeuristic(float a, float b) {
  if (std::isinf(a)) return 1.f;
  float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.f ? a2 / (a2 + b2) : 0.f;
}

// Unshadowed contribution f |cos| Le of a light sample, zero across the geometric surface.
inline Rgb unshadowedContribution(const ShadingPoint& sp, const LightSample& ls) {
  if (!(ls.pdf > 0.f) || isBlack(ls.radiance)) return Rgb(0.f);
  const Vec3 ng = sp.hit->ng;
  if (dot(ls.wi, ng) * dot(sp.woWorld, ng) <= 0.f) return Rgb(0.f);  // reflection only
  return sp.bsdf->eval(sp.wo, sp.frame.toLocal(ls.wi)) * ls.radiance;
}

inline bool traceShadow(const Scene& scene, const ShadingPoint& sp, const LightSample& ls, PathContext* ctx) {
  if (ctx && ctx->stats) ++ctx->stats->shadow;
  Vec3 o = Scene::shadowOrigin(sp.hit->p, sp.hit->ng, ls.wi);
  if (std::isinf(ls.dist)) {
    if (ctx && ctx->record) ctx->record->push_back({o, ls.wi, std::numeric_limits<float>::infinity(), true});
    return scene.occludedDirection(o, ls.wi);
  }
  // Area lights: step off the emitter towards the receiver; point lights have no surface.
  Vec3 target = isBlack(ls.lightNormal) ? ls.lightPoint : offsetOrigin(ls.lightPoint, ls.lightNormal, -ls.wi);
  Vec3 dir = ls.wi;
  float tmax = 0.f;
  bool blocked = scene.occludedSegment(o, target, dir, tmax);
  if (ctx && ctx->record) ctx->record->push_back({o, dir, tmax, true});
  return blocked;
}

// Baseline: one light chosen by power, MIS-weighted against BSDF sampling (the BSDF-sampled half
// is added by the path tracer when its ray hits an emitter).
Rgb estimateDirectNeeMis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx);

// Streaming RIS with M candidates drawn by the NEE strategy, target luminance(f |cos| Le)
// (times visibility when visibilityInTarget), Alg. 1 of Wang et al. 2023.
Rgb estimateDirectRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates,
                      bool visibilityInTarget, PathContext* ctx);

}  // namespace invr
