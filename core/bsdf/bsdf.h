// Materials and the BSDF evaluated at a shading point. One small value type with a switch keeps
// the hot path free of virtual calls; each lobe's maths lives in its own header.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/bsdf/bsdf_sample.h"
#include "core/bsdf/dielectric.h"
#include "core/bsdf/diffuse.h"
#include "core/bsdf/mirror.h"
#include "core/bsdf/rough_conductor.h"
#include "core/bsdf/rough_plastic.h"
#include "core/image/texture.h"

namespace invr {

enum class BsdfKind { Diffuse, RoughConductor, RoughPlastic, Mirror, Dielectric };

// GGX alpha below this is treated as this (keeps D finite; near-mirror surfaces should use Mirror).
inline constexpr float kMinAlpha = 1e-3f;

// A BSDF with its textures already looked up. Directions are in the local shading frame.
// Opaque lobes are two-sided unless oneSided: when wo is below the surface both directions are
// mirrored.
struct Bsdf {
  BsdfKind kind = BsdfKind::Diffuse;
  Rgb albedo{0.5f};
  float alpha = 0.1f;
  Rgb eta{1.f}, k{0.f};
  float ior = 1.5f;
  Rgb reflectance{1.f};
  bool oneSided = false;  // opaque lobes are black from the back (Material::oneSided)
  // Material::geometricSide: the caller's shading frame is already turned to wo's geometric side
  // (shadingFrame in core/render/direct_light.h), so wo below the shading horizon neither mirrors
  // the lobe nor blackens it. Diffuse only.
  bool geometricSide = false;

  bool isDelta() const { return kind == BsdfKind::Mirror || kind == BsdfKind::Dielectric; }
  // Seen from the back of a one-sided material: no reflection at all.
  bool blackFrom(Vec3 wo) const { return oneSided && kind != BsdfKind::Dielectric && wo.z < 0.f; }

  // BSDF value times |cos theta_i|.
  Rgb eval(Vec3 wo, Vec3 wi) const {
    if (geometricSide) return wi.z > 0.f ? albedo * (kInvPi * wi.z) : Rgb(0.f);
    if (isDelta() || blackFrom(wo)) return Rgb(0.f);
    if (wo.z < 0.f) { wo.z = -wo.z; wi.z = -wi.z; }
    switch (kind) {
      case BsdfKind::Diffuse: return diffuse::eval(albedo, wo, wi);
      case BsdfKind::RoughConductor: return rough_conductor::eval(alpha, eta, k, wo, wi);
      case BsdfKind::RoughPlastic: return rough_plastic::eval(albedo, alpha, ior, wo, wi);
      default: return Rgb(0.f);
    }
  }
  // Adjoint of eval (delta lobes have no differentiable parameters here).
  BsdfDerivatives evalDerivatives(Vec3 wo, Vec3 wi) const {
    if (geometricSide) {
      BsdfDerivatives d;
      if (wi.z > 0.f) d.dAlbedo = Rgb(kInvPi * wi.z);
      return d;
    }
    if (isDelta() || blackFrom(wo)) return {};
    if (wo.z < 0.f) { wo.z = -wo.z; wi.z = -wi.z; }
    switch (kind) {
      case BsdfKind::Diffuse: return diffuse::evalDerivatives(wo, wi);
      case BsdfKind::RoughConductor: return rough_conductor::evalDerivatives(alpha, eta, k, wo, wi);
      case BsdfKind::RoughPlastic: return rough_plastic::evalDerivatives(alpha, ior, wo, wi);
      default: return {};
    }
  }
  float pdf(Vec3 wo, Vec3 wi) const {
    if (geometricSide) return wi.z > 0.f ? cosineHemispherePdf(wi.z) : 0.f;
    if (isDelta() || blackFrom(wo)) return 0.f;
    if (wo.z < 0.f) { wo.z = -wo.z; wi.z = -wi.z; }
    switch (kind) {
      case BsdfKind::Diffuse: return diffuse::pdf(wo, wi);
      case BsdfKind::RoughConductor: return rough_conductor::pdf(alpha, wo, wi);
      case BsdfKind::RoughPlastic: return rough_plastic::pdf(albedo, alpha, ior, wo, wi);
      default: return 0.f;
    }
  }
  // The density sample() draws wi with (non-delta lobes), over the whole sphere: directions that
  // sample() rejects after drawing them (below the horizon) keep their density. With its
  // derivatives, what variance estimators need for the score of a BSDF decision (Yan et al. 2024).
  PdfDerivatives sampledPdf(Vec3 wo, Vec3 wi) const {
    if (geometricSide) {
      PdfDerivatives d;
      d.pdf = wi.z > 0.f ? cosineHemispherePdf(wi.z) : 0.f;
      return d;
    }
    if (isDelta() || blackFrom(wo)) return {};
    if (wo.z < 0.f) { wo.z = -wo.z; wi.z = -wi.z; }
    switch (kind) {
      case BsdfKind::Diffuse: return diffuse::sampledPdf(wo, wi);
      case BsdfKind::RoughConductor: return rough_conductor::sampledPdf(alpha, wo, wi);
      case BsdfKind::RoughPlastic: return rough_plastic::sampledPdf(albedo, alpha, ior, wo, wi);
      default: return {};
    }
  }
  // The direction sample() draws from (uc, u) before any rejection (non-delta lobes).
  Vec3 sampledDirection(Vec3 wo, float uc, Vec2 u) const {
    if (geometricSide) return sampleCosineHemisphere(u);
    bool flip = wo.z < 0.f;
    if (flip) wo.z = -wo.z;
    Vec3 wi;
    switch (kind) {
      case BsdfKind::RoughConductor: wi = rough_conductor::sampledDirection(alpha, wo, u); break;
      case BsdfKind::RoughPlastic: wi = rough_plastic::sampledDirection(albedo, alpha, ior, wo, uc, u); break;
      default: wi = sampleCosineHemisphere(u); break;
    }
    if (flip) wi.z = -wi.z;
    return wi;
  }
  std::optional<BsdfSample> sample(Vec3 wo, float uc, Vec2 u) const {
    if (kind == BsdfKind::Dielectric) return dielectric::sample(ior, wo, uc);
    if (geometricSide) {
      const Vec3 wi = sampleCosineHemisphere(u);
      if (wi.z <= 0.f) return std::nullopt;
      return BsdfSample{wi, albedo, cosineHemispherePdf(wi.z)};
    }
    if (blackFrom(wo)) return std::nullopt;
    bool flip = wo.z < 0.f;
    if (flip) wo.z = -wo.z;
    std::optional<BsdfSample> s;
    switch (kind) {
      case BsdfKind::Diffuse: s = diffuse::sample(albedo, wo, u); break;
      case BsdfKind::RoughConductor: s = rough_conductor::sample(alpha, eta, k, wo, u); break;
      case BsdfKind::RoughPlastic: s = rough_plastic::sample(albedo, alpha, ior, wo, uc, u); break;
      case BsdfKind::Mirror: s = mirror::sample(reflectance, wo); break;
      default: break;
    }
    if (s && flip) s->wi.z = -s->wi.z;
    return s;
  }
};

struct Material {
  std::string name;
  BsdfKind kind = BsdfKind::Diffuse;
  Texture albedo{Rgb(0.5f)};
  Texture roughness{Rgb(0.1f)};
  Rgb eta{1.f}, k{0.f};
  float ior = 1.5f;
  Rgb reflectance{1.f};
  bool oneSided = false;  // black from the back, like Mitsuba's bsdfs outside `twosided`
  // Set on the diffuse material of a smooth-shaded (interpolated-normal) mesh when it first moves
  // (Scene::applyShapeMotion): its side is the geometric one, not the shading normal's (Bsdf).
  bool geometricSide = false;
  std::vector<std::string> aliases;  // other names parameters may use (Mitsuba ids folded into this one)

  bool hasAlbedo() const { return kind == BsdfKind::Diffuse || kind == BsdfKind::RoughPlastic; }
  bool hasRoughness() const { return kind == BsdfKind::RoughConductor || kind == BsdfKind::RoughPlastic; }

  Bsdf at(Vec2 uv) const {
    Bsdf b;
    b.kind = kind;
    if (kind == BsdfKind::Diffuse || kind == BsdfKind::RoughPlastic) b.albedo = albedo.eval(uv);
    if (kind == BsdfKind::RoughConductor || kind == BsdfKind::RoughPlastic)
      b.alpha = std::max(roughness.evalScalar(uv), kMinAlpha);
    b.eta = eta; b.k = k; b.ior = ior; b.reflectance = reflectance;
    b.oneSided = oneSided;
    b.geometricSide = geometricSide && kind == BsdfKind::Diffuse;
    return b;
  }
};

}  // namespace invr
