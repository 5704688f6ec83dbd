// GGX microfacet conductor: f = F(wo.m) D(m) G2 / (4 cos_o cos_i), sampled with visible normals.
#pragma once

#include <optional>

#include "core/bsdf/bsdf_sample.h"
#include "core/bsdf/fresnel.h"
#include "core/bsdf/microfacet.h"

namespace invr::rough_conductor {

inline Rgb eval(float alpha, Rgb eta, Rgb k, Vec3 wo, Vec3 wi) {
  if (wo.z <= 0.f || wi.z <= 0.f) return Rgb(0.f);
  Vec3 m = normalize(wo + wi);
  return fresnelConductor(dot(wo, m), eta, k) * (ggx::D(m, alpha) * ggx::G2(wo, wi, alpha) / (4.f * wo.z));
}
// Adjoint of eval with respect to alpha (Fresnel does not depend on it).
inline BsdfDerivatives evalDerivatives(float alpha, Rgb eta, Rgb k, Vec3 wo, Vec3 wi) {
  BsdfDerivatives d;
  if (wo.z <= 0.f || wi.z <= 0.f) return d;
  Vec3 m = normalize(wo + wi);
  d.dAlpha = fresnelConductor(dot(wo, m), eta, k) * (ggx::dDG2_dAlpha(m, wo, wi, alpha) / (4.f * wo.z));
  return d;
}
inline float pdf(float alpha, Vec3 wo, Vec3 wi) {
  if (wo.z <= 0.f || wi.z <= 0.f) return 0.f;
  return ggx::pdfReflect(wo, wi, alpha);
}
// The density sample() draws wi with, over the whole sphere (sample() rejects the reflections
// that fall below the horizon, but it drew them with this density), and its adjoint.
inline PdfDerivatives sampledPdf(float alpha, Vec3 wo, Vec3 wi) {
  PdfDerivatives d;
  if (wo.z <= 0.f) return d;
  d.pdf = ggx::pdfReflect(wo, wi, alpha);
  d.dAlpha = ggx::dPdfReflect_dAlpha(wo, wi, alpha);
  return d;
}
// The direction sample() draws from u before rejecting anything.
inline Vec3 sampledDirection(float alpha, Vec3 wo, Vec2 u) { return ggx::reflect(wo, ggx::sampleVisible(wo, alpha, u)); }
inline std::optional<BsdfSample> sample(float alpha, Rgb eta, Rgb k, Vec3 wo, Vec2 u) {
  if (wo.z <= 0.f) return std::nullopt;
  Vec3 m = ggx::sampleVisible(wo, alpha, u);
  Vec3 wi = ggx::reflect(wo, m);
  if (wi.z <= 0.f) return std::nullopt;
  float p = ggx::pdfVisible(wo, m, alpha) / (4.f * dot(wo, m));
  if (!(p > 0.f)) return std::nullopt;
  // f cos / pdf simplifies to F G2 / G1(wo).
  Rgb w = fresnelConductor(dot(wo, m), eta, k) * (ggx::G2(wo, wi, alpha) / ggx::G1(wo, alpha));
  return BsdfSample{wi, w, p};
}

}  // namespace invr::rough_conductor
