// Direct illumination at one surface vertex, as sampled paths (x0 on a light, x1 here, x2 the
// previous vertex). A path contributes weight * bsdfValue * emission, where `weight` collects every
// factor that the estimator treats as detached (pdfs, geometry, visibility, RIS weights, MIS) and
// the other two factors are the only ones that depend on material and light parameters. The
// forward renderer sums contributions; the gradient engine differentiates bsdfValue and emission.
#pragma once

#include <new>

#include "core/math/rng.h"
#include "core/render/render_options.h"
#include "core/render/reservoir.h"
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
  // NEE only: the light-half MIS weight inside `weight`, and whether MIS applied (not for delta lights).
  float mis = 1.f;
  bool misWeighted = false;
  Rgb contribution() const { return weight * bsdfValue * emission; }
};

inline float powerHeuristic(float a, float b) {
  if (std::isinf(a)) return 1.f;
  float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.f ? a2 / (a2 + b2) : 0.f;
}

// The shading frame at a hit seen from woWorld: about the shading normal, turned to the geometric
// side wo is on when the material asks (Bsdf::geometricSide). Then the shading normal's own horizon
// (ns . wo = 0, a curve inside the faces next to a smooth mesh's silhouette) does not switch the
// lobe: that curve moves with the mesh and no boundary term samples it.
inline Frame shadingFrame(const SurfaceHit& h, const Bsdf& b, Vec3 woWorld) {
  return Frame(b.geometricSide && dot(h.ng, woWorld) < 0.f ? -h.ns : h.ns);
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
  if (std::isinf(ls.dist)) return scene.occludedDirection(o, ls.wi);
  // Area lights: step off the emitter towards the receiver; point lights have no surface.
  Vec3 target = isBlack(ls.lightNormal) ? ls.lightPoint : offsetOrigin(ls.lightPoint, ls.lightNormal, -ls.wi);
  Vec3 dir = ls.wi;
  float tmax = 0.f;
  return scene.occludedSegment(o, target, dir, tmax);
}

// Shadow rays from one shading point, queued as traceShadow would trace them and answered together
// in one Embree packet (a shading point's candidates share an origin: coherent rays).
class ShadowPacket {
 public:
  static constexpr int kCapacity = EmbreeScene::kPacket;
  ShadowPacket() {}  // the ray slots are written before they are read: no initialisation
  // Queues the ray sp -> ls and returns its slot, or -1 for a degenerate segment (never blocked,
  // as traceShadow answers; counted all the same). At most kCapacity rays between clears.
  int push(const ShadingPoint& sp, const LightSample& ls, PathContext* ctx) {
    if (ctx && ctx->stats) ++ctx->stats->shadow;
    const Vec3 o = Scene::shadowOrigin(sp.hit->p, sp.hit->ng, ls.wi);
    if (std::isinf(ls.dist)) return add(o, ls.wi, std::numeric_limits<float>::infinity());
    const Vec3 target = isBlack(ls.lightNormal) ? ls.lightPoint : offsetOrigin(ls.lightPoint, ls.lightNormal, -ls.wi);
    const Vec3 d = target - o;
    const float len = length(d);
    if (!(len > 0.f)) return -1;
    return add(o, d / len, len);
  }
  // A packet when it pays (half full at least, and a scene where packets win: EmbreeScene), else
  // ray by ray (a packet may round a ray grazing an edge differently: EmbreeScene::occludedPacket).
  void trace(const Scene& scene) {
    if (n_ >= kCapacity / 2 && scene.accel.shadowPacketsPay()) {
      scene.accel.occludedPacket(n_, o_, d_, tmax_, blocked_);
      return;
    }
    for (int i = 0; i < n_; ++i) blocked_[i] = scene.accel.occluded(o_[i], d_[i], 0.f, tmax_[i]);
  }
  bool blocked(int slot) const { return slot >= 0 && blocked_[slot]; }
  int size() const { return n_; }
  void clear() { n_ = 0; }

 private:
  int add(Vec3 o, Vec3 d, float tmax) {
    o_[n_] = o;
    d_[n_] = d;
    tmax_[n_] = tmax;
    return n_++;
  }
  union {
    Vec3 o_[kCapacity];
  };
  union {
    Vec3 d_[kCapacity];
  };
  float tmax_[kCapacity];
  bool blocked_[kCapacity];
  int n_ = 0;
};

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
// `lightPmf` (optional, one per light) replaces the scene's selection (per-pixel selection);
// `chosen` (optional) receives the light picked, whether or not it contributes: variance
// estimators score every random choice.
bool sampleDirectNee(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx, DirectPath& out,
                     const float* lightPmf = nullptr, int* chosen = nullptr);

// Index drawn from a small pmf (sums to 1) by a linear scan; the last positive entry absorbs rounding.
inline size_t sampleSmallPmf(const float* pmf, size_t n, float u) {
  float acc = 0.f;
  size_t last = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!(pmf[i] > 0.f)) continue;
    last = i;
    acc += pmf[i];
    if (u < acc) return i;
  }
  return last;
}

// Delta lights as seen from one shading point. A point or spot light is a single sample whatever
// the random numbers, so the RIS candidates that pick it again and the ReSTIR neighbours that
// carry it all share one evaluation (sample, f |cos|, target) and one shadow ray.
class DeltaLightCache {
 public:
  struct Entry {
    LightSample ls;
    Rgb f;
    float target;    // risTarget (may be non-finite: every use checks)
    int8_t occluded;  // -1: no ray traced yet
  };
  DeltaLightCache() {}
  DeltaLightCache(const DeltaLightCache&) = delete;
  DeltaLightCache& operator=(const DeltaLightCache&) = delete;
  ~DeltaLightCache() {
    for (int i = 0; i < n_; ++i) entry(i).~Entry();
  }

  // The evaluation of delta light `light` (an index into scene.lights) at sp, computed on first
  // use; null when every slot is taken (the caller evaluates it itself).
  Entry* at(const Scene& scene, const ShadingPoint& sp, uint32_t light) {
    for (int i = 0; i < n_; ++i)
      if (light_[i] == light) return &entry(i);
    if (n_ == kSlots) return nullptr;
    light_[n_] = light;
    Entry* e = new (&storage_[n_++]) Entry{sampleLight(scene.lights[light], scene, sp.hit->p, Vec2(0.f, 0.f), light), Rgb(0.f), 0.f, -1};
    e->target = risTarget(sp, e->ls, &e->f);
    return e;
  }
  // Whether e's light is occluded from sp, tracing its shadow ray on the first ask only.
  static bool occluded(Entry& e, const Scene& scene, const ShadingPoint& sp, PathContext* ctx) {
    if (e.occluded < 0) e.occluded = traceShadow(scene, sp, e.ls, ctx) ? 1 : 0;
    return e.occluded > 0;
  }
  // What is known about delta lights 0..7 as bit masks (bit i: light i traced; light i visible).
  void bits(uint8_t& known, uint8_t& visible) {
    known = visible = 0;
    for (int i = 0; i < n_; ++i)
      if (light_[i] < 8 && entry(i).occluded >= 0) {
        known |= uint8_t(1u << light_[i]);
        if (entry(i).occluded == 0) visible |= uint8_t(1u << light_[i]);
      }
  }

 private:
  static constexpr int kSlots = 8;
  struct alignas(Entry) Slot {
    unsigned char bytes[sizeof(Entry)];
  };
  Entry& entry(int i) { return *std::launder(reinterpret_cast<Entry*>(&storage_[i])); }
  uint32_t light_[kSlots];
  Slot storage_[kSlots];  // constructed on first use: most points see few delta lights
  int n_ = 0;
};

// Streaming RIS core (Alg. 1): the reservoir after M candidates, and the chosen sample's data.
// A candidate with a non-finite target sets *nonFinite (the caller drops the whole sample).
// `deltas` (optional) carries the delta-light evaluations and shadow rays to the caller's later
// uses at sp.
Reservoir streamRis(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibilityInTarget,
                    PathContext* ctx, LightSample& chosen, Rgb& chosenF, bool* nonFinite = nullptr,
                    DeltaLightCache* deltas = nullptr);

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
