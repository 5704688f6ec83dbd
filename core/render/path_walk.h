// The one random walk every path-space estimator in invr shares: the forward renderer, the
// gradient engine's PT / RIS / ReSTIR camera samples and the multi-bounce derivatives visit it.
// Emission, the BSDF half of MIS, shading-normal rejection and Russian roulette are written here
// once; what differs between uses is
//   - the direct-light strategy at each vertex (NEE + MIS, streaming RIS, ReSTIR), a callable
//       bool direct(const ShadingPoint&, int depth, Sampler&, PathContext*, DirectPath& out);
//   - the visitor that receives every contribution with the factors it needs:
//       emission(Rgb weight, Rgb Le, const LightSampleRef& light, float perUnit)
//       direct(Rgb beta, const DirectPath& p, const WalkVertex& v)
//       bounce(const WalkVertex& v, Vec3 wiLocal)         (non-delta continuations only)
// Visitors that differentiate sampling densities (variance, core/diff/variance_visitor.h) also
// define, and are detected by:
//       emission(weight, Le, light, perUnit, EmissionMis)   (the BSDF-half MIS weight applied)
//       rejected(const WalkVertex& v, float uc, Vec2 u)      (a BSDF draw the walk rejected)
//       roulette(q, survived, channel, depth)                (channel: throughput RR's max channel, or -1;
//                                                              depth: the vertex whose bounce it follows;
//                                                              fixed survival reports q = 1 too, survived)
// Random numbers are consumed in a fixed order, so equal samplers walk equal paths. `primary`, when
// given, is the camera ray's closest hit traced beforehand (the walk then traces from the first
// vertex on).
#pragma once

#include "core/render/direct_light.h"

namespace invr {

struct WalkSettings {
  int maxDepth = 1;              // path vertices after the camera; 1 = direct illumination
  int russianRouletteDepth = 3;  // roulette after this many bounces
  // true: the direct strategy is NEE + MIS, so emission reached through a non-delta lobe is
  // weighted by the BSDF half of the power heuristic. false (RIS, ReSTIR): the direct strategy
  // alone accounts for emission seen through non-delta lobes.
  bool bsdfMis = true;
  // Per camera sample: the light-selection pmf (one per light) when it is not the scene's
  // (per-pixel selection); the direct strategy must sample with the same one.
  const float* lightPmf = nullptr;
};

// The BSDF half of MIS as applied to emission reached by BSDF sampling: w = pdf_bsdf^2 /
// (pdf_bsdf^2 + pdf_light^2); `weighted` is false after the camera or a delta lobe (w = 1).
struct EmissionMis {
  float w = 1.f;
  bool weighted = false;
};

// One surface vertex as a visitor sees it.
struct WalkVertex {
  const SurfaceHit* hit;
  const Bsdf* bsdf;
  int material;
  Vec3 wo;  // local
  int depth;
  const Frame* frame;  // the shading frame wo is local to (shadingFrame)
};

template <class Direct, class Visitor>
void walkPath(const Scene& scene, Vec3 o, Vec3 d, Sampler& sampler, const WalkSettings& s, Direct& direct, Visitor& v,
              PathContext* ctx, const PrimaryHit* primary = nullptr) {
  Rgb beta(1.f);
  bool specular = true;  // the camera or a delta lobe: emission is not covered by the direct strategy
  float prevBsdfPdf = 0.f;
  Vec3 prevP = o;
  const auto& select = scene.lightSelection();
  auto pmfOf = [&](size_t li) { return s.lightPmf ? s.lightPmf[li] : select.pmf(li); };
  auto emit = [&](Rgb weight, Rgb Le, const LightSampleRef& ref, float perUnit, EmissionMis mis) {
    if constexpr (requires { v.emission(weight, Le, ref, perUnit, mis); }) v.emission(weight, Le, ref, perUnit, mis);
    else v.emission(weight, Le, ref, perUnit);
  };
  auto rejected = [&](const WalkVertex& vx, float uc, Vec2 u) {
    if constexpr (requires { v.rejected(vx, uc, u); }) v.rejected(vx, uc, u);
  };
  const std::vector<float>& survival = scene.sampling.survival;
  for (int depth = 0;; ++depth) {
    if (ctx && ctx->stats) {
      ++(depth == 0 ? ctx->stats->camera : ctx->stats->bounce);
      ++ctx->stats->byDepth[depth];
    }
    SurfaceHit hit;
    bool found;
    if (depth == 0 && primary) {  // traced already, with the camera rays of its neighbours
      found = primary->found;
      if (found) hit = primary->hit;
    } else {
      found = scene.intersect(o, d, hit);
    }
    if (!found) {
      if (!specular && !s.bsdfMis) return;
      for (uint32_t li : scene.infiniteLights()) {
        const Light& l = scene.lights[li];
        Rgb Le = environmentRadiance(l, d);
        if (isBlack(Le)) continue;
        float w = specular ? 1.f : powerHeuristic(prevBsdfPdf, pmfOf(li) * environmentPdf(l, d));
        LightSampleRef ref;
        ref.light = li;
        ref.setDirection(d);
        emit(beta * w, Le, ref, l.scale, EmissionMis{w, !specular});
      }
      return;
    }
    if (int li = scene.meshLight[hit.mesh]; li >= 0 && (specular || s.bsdfMis)) {
      const Light& l = scene.lights[size_t(li)];
      Rgb Le = areaEmission(l, hit.ng, -d);
      if (!isBlack(Le)) {
        float w = specular ? 1.f : powerHeuristic(prevBsdfPdf, pmfOf(size_t(li)) * areaLightPdf(l, prevP, hit.p, hit.ng));
        LightSampleRef ref;
        ref.light = uint32_t(li);
        ref.tri = hit.tri;
        ref.b1 = hit.b1;
        ref.b2 = hit.b2;
        emit(beta * w, Le, ref, l.scale, EmissionMis{w, !specular});
      }
    }
    if (depth >= s.maxDepth) return;

    const int material = scene.meshMaterial[hit.mesh];
    const Bsdf bsdf = scene.materials[size_t(material)].at(hit.uv);
    ShadingPoint sp{&hit, &bsdf, shadingFrame(hit, bsdf, -d), Vec3(), -d};
    sp.wo = sp.frame.toLocal(-d);
    const WalkVertex vx{&hit, &bsdf, material, sp.wo, depth, &sp.frame};
    if (!bsdf.isDelta()) {
      DirectPath p;
      const uint64_t shadowBefore = ctx && ctx->stats ? ctx->stats->shadow : 0;
      sampler.beginDomain(SampleDomain::directLight(depth));
      if (direct(sp, depth, sampler, ctx, p)) v.direct(beta, p, vx);
      if (ctx && ctx->stats) ctx->stats->byDepth[depth] += ctx->stats->shadow - shadowBefore;
    }
    // At the last vertex the continuation only adds emission: needed for the BSDF half of MIS and
    // after delta lobes; without MIS the direct strategy covers what rough lobes see.
    if (depth + 1 >= s.maxDepth && !s.bsdfMis && !bsdf.isDelta()) return;

    sampler.beginDomain(SampleDomain::bsdf(depth));
    float uc = sampler.next1D();
    const Vec2 u2 = sampler.next2D();
    const Vec2 u(u2.y, u2.x);  // y drawn first: the independent streams' order before 2D draws
    auto bs = bsdf.sample(sp.wo, uc, u);
    if (!bs) {
      if (!bsdf.isDelta()) rejected(vx, uc, u);
      return;
    }
    Vec3 wi = sp.frame.toWorld(bs->wi);
    // Shading normals can send a reflection below the geometric surface (or the reverse): drop it.
    float side = dot(wi, hit.ng) * dot(-d, hit.ng);
    if (bs->transmitted ? side >= 0.f : side <= 0.f) {
      if (!bs->delta) rejected(vx, uc, u);
      return;
    }
    if (!bs->delta) v.bounce(vx, bs->wi);
    beta *= bs->weight;
    specular = bs->delta;
    prevBsdfPdf = bs->pdf;
    prevP = hit.p;
    o = offsetOrigin(hit.p, hit.ng, wi);
    d = wi;
    auto roulette = [&](float q, bool survived, int channel) {
      if constexpr (requires { v.roulette(q, survived, channel, depth); }) v.roulette(q, survived, channel, depth);
    };
    sampler.beginDomain(SampleDomain::roulette(depth));
    if (!survival.empty()) {  // fixed survival per bounce (bounce depth + 1)
      float q = survival[std::min(size_t(depth), survival.size() - 1)];
      if (q < 1.f) {
        bool survived = sampler.next1D() < q;
        roulette(q, survived, -1);
        if (!survived) return;
        beta = beta / q;
      } else {
        roulette(1.f, true, -1);  // certain: no random number, but q = 1 still has a (left) derivative
      }
    } else if (depth + 1 >= s.russianRouletteDepth) {
      float m = maxComponent(beta);
      float q = std::min(1.f, m);
      bool survived = sampler.next1D() < q;
      if (q < 1.f) roulette(q, survived, beta.x == m ? 0 : beta.y == m ? 1 : 2);
      if (!survived) return;
      beta = beta / q;
    }
  }
}

// Radiance only (the forward renderer and primal passes).
struct RadianceVisitor {
  Rgb L{0.f};
  void emission(Rgb weight, Rgb Le, const LightSampleRef&, float) { L += weight * Le; }
  void direct(Rgb beta, const DirectPath& p, const WalkVertex&) { L += beta * p.contribution(); }
  void bounce(const WalkVertex&, Vec3) {}
};

// Direct-light strategies of the forward renderer.
struct NeeMisDirect {
  const Scene& scene;
  const float* lightPmf = nullptr;  // per-pixel selection (WalkSettings::lightPmf), or the scene's
  bool operator()(const ShadingPoint& sp, int, Sampler& sampler, PathContext* ctx, DirectPath& out) const {
    return sampleDirectNee(scene, sp, sampler, ctx, out, lightPmf);
  }
};

// The light-selection pmf of pixel (x, y) of `view` when the scene has a per-pixel logit map for
// it (written into `pmf`, which is returned), else null (the scene's selection applies).
inline const float* pixelLightPmf(const Scene& scene, int view, int x, int y, std::vector<float>& pmf, int* cell = nullptr) {
  if (size_t(view) >= scene.sampling.pixelLogits.size() || scene.sampling.pixelLogits[size_t(view)].empty()) return nullptr;
  const auto& map = scene.sampling.pixelLogits[size_t(view)];
  const size_t n = scene.lights.size();
  const int c = (y * map.height / scene.height) * map.width + x * map.width / scene.width;
  if (cell) *cell = c;
  pmf.resize(n);
  const float* logits = map.logits.data() + size_t(c) * n;
  float top = logits[0];
  for (size_t i = 1; i < n; ++i) top = std::max(top, logits[i]);
  double sum = 0;
  for (size_t i = 0; i < n; ++i) sum += (pmf[i] = std::exp(logits[i] - top));
  for (size_t i = 0; i < n; ++i) pmf[i] = float(double(pmf[i]) / sum);
  return pmf.data();
}

struct RisDirect {
  const Scene& scene;
  int candidates;
  bool visibilityInTarget;
  bool operator()(const ShadingPoint& sp, int, Sampler& sampler, PathContext* ctx, DirectPath& out) const {
    return sampleDirectRis(scene, sp, sampler, candidates, visibilityInTarget, ctx, out);
  }
};

}  // namespace invr
