// Diffuse base under a GGX dielectric interface. The base is attenuated by the Fresnel
// transmittance in and out, which keeps the model energy-conserving without internal scattering.
#pragma once

#include <optional>

#include "core/bsdf/bsdf_sample.h"
#include "core/bsdf/fresnel.h"
#include "core/bsdf/microfacet.h"
#include "core/math/sampling.h"

namespace invr::rough_plastic {

// Probability of sampling the specular lobe; depends on wo only so pdf() can recompute it.
inline float specularProbability(Rgb albedo, float ior, Vec3 wo) {
  float f = fresnelDielectric(wo.z, ior);
  float d = (1.f - f) * std::max(luminance(albedo), 0.f);
  return clamp(f / std::max(f + d, 1e-6f), 0.1f, 0.9f);
}

// Adjoint of specularProbability with respect to the albedo, per channel (zero where clamped).
inline Rgb dSpecularProbability_dAlbedo(Rgb albedo, float ior, Vec3 wo) {
  float f = fresnelDielectric(wo.z, ior);
  float lum = luminance(albedo);
  if (!(lum > 0.f)) return Rgb(0.f);
  float d = (1.f - f) * lum;
  if (!(f + d > 1e-6f)) return Rgb(0.f);
  float ps = f / (f + d);
  if (ps <= 0.1f || ps >= 0.9f) return Rgb(0.f);
  float dPs_dLum = -f * (1.f - f) / ((f + d) * (f + d));
  return luminanceWeights() * dPs_dLum;
}

inline Rgb eval(Rgb albedo, float alpha, float ior, Vec3 wo, Vec3 wi) {
  if (wo.z <= 0.f || wi.z <= 0.f) return Rgb(0.f);
  Vec3 m = normalize(wo + wi);
  float spec = fresnelDielectric(dot(wo, m), ior) * ggx::D(m, alpha) * ggx::G2(wo, wi, alpha) / (4.f * wo.z);
  float trans = (1.f - fresnelDielectric(wo.z, ior)) * (1.f - fresnelDielectric(wi.z, ior));
  return albedo * (trans * kInvPi * wi.z) + Rgb(spec);
}

// Adjoint of eval: the diffuse base is linear in albedo, the coating depends on alpha.
inline BsdfDerivatives evalDerivatives(float alpha, float ior, Vec3 wo, Vec3 wi) {
  BsdfDerivatives d;
  if (wo.z <= 0.f || wi.z <= 0.f) return d;
  Vec3 m = normalize(wo + wi);
  float trans = (1.f - fresnelDielectric(wo.z, ior)) * (1.f - fresnelDielectric(wi.z, ior));
  d.dAlbedo = Rgb(trans * kInvPi * wi.z);
  d.dAlpha = Rgb(fresnelDielectric(dot(wo, m), ior) * ggx::dDG2_dAlpha(m, wo, wi, alpha) / (4.f * wo.z));
  return d;
}

inline float pdf(Rgb albedo, float alpha, float ior, Vec3 wo, Vec3 wi) {
  if (wo.z <= 0.f || wi.z <= 0.f) return 0.f;
  float ps = specularProbability(albedo, ior, wo);
  return ps * ggx::pdfReflect(wo, wi, alpha) + (1.f - ps) * cosineHemispherePdf(wi.z);
}

// The mixture density sample() draws wi with, over the whole sphere (the specular lobe's
// reflections below the horizon are drawn, then rejected), and its adjoint: the lobe choice
// depends on the albedo, the specular lobe on alpha.
inline PdfDerivatives sampledPdf(Rgb albedo, float alpha, float ior, Vec3 wo, Vec3 wi) {
  PdfDerivatives d;
  if (wo.z <= 0.f) return d;
  float ps = specularProbability(albedo, ior, wo);
  float spec = ggx::pdfReflect(wo, wi, alpha), diff = wi.z > 0.f ? cosineHemispherePdf(wi.z) : 0.f;
  d.pdf = ps * spec + (1.f - ps) * diff;
  d.dAlpha = ps * ggx::dPdfReflect_dAlpha(wo, wi, alpha);
  d.dAlbedo = dSpecularProbability_dAlbedo(albedo, ior, wo) * (spec - diff);
  return d;
}
inline Vec3 sampledDirection(Rgb albedo, float alpha, float ior, Vec3 wo, float uc, Vec2 u) {
  return uc < specularProbability(albedo, ior, wo) ? ggx::reflect(wo, ggx::sampleVisible(wo, alpha, u)) : sampleCosineHemisphere(u);
}

inline std::optional<BsdfSample> sample(Rgb albedo, float alpha, float ior, Vec3 wo, float uc, Vec2 u) {
  if (wo.z <= 0.f) return std::nullopt;
  float ps = specularProbability(albedo, ior, wo);
  Vec3 wi = uc < ps ? ggx::reflect(wo, ggx::sampleVisible(wo, alpha, u)) : sampleCosineHemisphere(u);
  if (wi.z <= 0.f) return std::nullopt;
  float p = pdf(albedo, alpha, ior, wo, wi);
  if (!(p > 0.f)) return std::nullopt;
  return BsdfSample{wi, eval(albedo, alpha, ior, wo, wi) / p, p};
}

}  // namespace invr::rough_plastic
