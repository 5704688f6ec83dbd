// Direct illumination at one surface vertex, as sampled paths (x0 on a light, x1 here, x2 the
// previous vertex). A path contributes weight * bsdfValue * emission, where `weight` collects every
// factor that the estimator treats as detached (pdfs, geometry, visibility, RIS weights, MIS) and
// the other two factors are the only ones that depend on material and light parameters. The
// forward renderer sums contributions; the gradient engine differentiates bsdfValue and emission.
#pragma once

#include "core/math/rng.h"
#include "core/render/render_options.h"
#include "core/restir/reservoir.h"
#include "core/scene/scene.h"

namespace invr {

struct ShadingPoint {
  const SurfaceHit* hit;
  const Bsdf* bsdf;
  Frame frame;  // shading frame
  Vec3 wo;      // local
  Vec3 woWorld;
};

struct DirectPath {
  Rgb weight{0.f};
  Rgb bsdfValue{0.f};  // f |cos| at x1
  Rgb emission{0.f};   // Le arriving at x1 (point lights: includes falloff / d^2)
  Vec3 wiLocal;
  bool throughBsdf = true;  // false for emission seen directly or through a delta lobe
  LightSampleRef light;
  float emissionPerUnit = 0.f;  // d emission / d (light radiance or intensity)
  Rgb contribution() const { return weight * bsdfValue * emission; }
};

inline float powerHeuristic(float a, float b) {
  if (std::isinf(a)) return 1.f;
  float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.f ? a2 / (a2 + b2) : 0.f;
}

// f |cos| of a light sample at the shading point; zero across the geometric surface
// (all non-delta lobes here are reflective).
inline Rgb bsdfTowards(const ShadingPoint& sp, Vec3 wi) {
  const Vec3 ng = sp.hit->ng;
  if (dot(wi, ng) * dot(sp.woWorld, ng) <= 0.f) return Rgb(0.f);
  return sp.bsdf->eval(sp.wo, sp.frame.toLocal(wi));
}

// The resampling target in the light's native measure: luminance(f |cos| Le) * jacobian.
inline float risTarget(const ShadingPoint& sp, const LightSample& ls, Rgb* fOut = nullptr) {
  if (!(ls.pdfNative > 0.f) || isBlack(ls.radiance)) return 0.f;
  Rgb f = bsdfTowards(sp, ls.wi);
  if (fOut) *fOut = f;
  return luminance(f * ls.radiance) * ls.jacobian;
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

// A path to a light sample whose unbiased contribution weight (in the native measure) is W.
// A path that carries a non-finite value, so the caller's single non-finite check counts and drops
// the sample (a NaN parameter or an overflow inside a resampling weight must not turn into a silent
// zero).
inline DirectPath nonFinitePath() {
  DirectPath p;
  p.weight = Rgb(std::numeric_limits<float>::quiet_NaN());
  p.bsdfValue = Rgb(1.f);
  p.emission = Rgb(1.f);
  return p;
}

inline DirectPath pathToLight(const ShadingPoint& sp, const LightSample& ls, Rgb f, float W) {
  DirectPath p;
  p.weight = Rgb(W * ls.jacobian);
  p.bsdfValue = f;
  p.emission = ls.radiance;
  p.wiLocal = sp.frame.toLocal(ls.wi);
  p.light = ls.ref;
  p.emissionPerUnit = ls.emissionPerUnit;
  return p;
}

// Baseline B.1: one light chosen by power, MIS-weighted against BSDF sampling (the BSDF-sampled
// half is added by whoever traces the BSDF ray). False if the sample contributes nothing.
bool sampleDirectNee(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx, DirectPath& out);

// Shadow-ray results for delta lights from one shading point. A point or spot light is a single
// sample, so RIS candidates that pick it again (and ReSTIR neighbours that carry it) need no new
// ray: the answer is the same.
class DeltaVisibility {
 public:
  // Occlusion of ls (a sample of light `light`) from sp, tracing only on the first ask per delta light.
  bool occluded(const Scene& scene, const ShadingPoint& sp, const LightSample& ls, PathContext* ctx) {
    if (!ls.delta) return traceShadow(scene, sp, ls, ctx);
    for (int i = 0; i < n_; ++i)
      if (light_[i] == ls.ref.light) return occluded_[i];
    bool o = traceShadow(scene, sp, ls, ctx);
    if (n_ < kSlots) {
      light_[n_] = ls.ref.light;
      occluded_[n_++] = o;
    }
    return o;
  }
  // What is known about delta lights 0..7 as bit masks (bit i: light i traced; light i visible).
  void bits(uint8_t& known, uint8_t& visible) const {
    known = visible = 0;
    for (int i = 0; i < n_; ++i)
      if (light_[i] < 8) {
        known |= uint8_t(1u << light_[i]);
        if (!occluded_[i]) visible |= uint8_t(1u << light_[i]);
      }
  }

 private:
  static constexpr int kSlots = 8;
  uint32_t light_[kSlots];
  bool occluded_[kSlots];
  int n_ = 0;
};

// Streaming RIS core (Alg. 1): the reservoir after M candidates, and the chosen sample's data.
// A candidate with a non-finite target sets *nonFinite (the caller drops the whole sample).
// `visibility` (optional) carries delta-light shadow rays to the caller's later tests at sp.
Reservoir streamRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                    PathContext* ctx, LightSample& chosen, Rgb& chosenF, bool* nonFinite = nullptr,
                    DeltaVisibility* visibility = nullptr);

// Baseline B.2: streaming RIS over M candidates drawn by the NEE strategy (Alg. 1). The target
// includes visibility when visibilityInTarget (Eq. 14), else not (Eq. 17). `reservoir` receives
// the resampled state (for ReSTIR); returns false if the chosen sample contributes nothing.
bool sampleDirectRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                     PathContext* ctx, DirectPath& out, Reservoir* reservoir = nullptr);

// Forward-rendering wrappers: the estimate of direct light (without path throughput).
inline Rgb estimateDirectNeeMis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx) {
  DirectPath p;
  return sampleDirectNee(scene, sp, sampler, ctx, p) ? p.contribution() : Rgb(0.f);
}
inline Rgb estimateDirectRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates,
                             bool visibilityInTarget, PathContext* ctx) {
  DirectPath p;
  return sampleDirectRis(scene, sp, sampler, candidates, visibilityInTarget, ctx, p) ? p.contribution() : Rgb(0.f);
}

}  // namespace invr
