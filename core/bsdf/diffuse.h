// Lambertian reflection; two-sided (the caller flips the frame so wo.z > 0).
#pragma once

#include <optional>

#include "core/bsdf/bsdf_sample.h"
#include "core/math/sampling.h"

namespace invr::diffuse {

inline Rgb eval(Rgb albedo, Vec3 wo, Vec3 wi) {
  if (wo.z <= 0.f || wi.z <= 0.f) return Rgb(0.f);
  return albedo * (kInvPi * wi.z);
}
// Adjoint of eval: d eval_c / d albedo_c.
inline BsdfDerivatives evalDerivatives(Vec3 wo, Vec3 wi) {
  BsdfDerivatives d;
  if (wo.z > 0.f && wi.z > 0.f) d.dAlbedo = Rgb(kInvPi * wi.z);
  return d;
}
inline float pdf(Vec3 wo, Vec3 wi) { return wo.z > 0.f ? cosineHemispherePdf(wi.z) : 0.f; }
// Cosine sampling draws no direction below the horizon; no parameter enters its density.
inline PdfDerivatives sampledPdf(Vec3 wo, Vec3 wi) {
  PdfDerivatives d;
  d.pdf = pdf(wo, wi);
  return d;
}
inline std::optional<BsdfSample> sample(Rgb albedo, Vec3 wo, Vec2 u) {
  if (wo.z <= 0.f) return std::nullopt;
  Vec3 wi = sampleCosineHemisphere(u);
  if (wi.z <= 0.f) return std::nullopt;
  return BsdfSample{wi, albedo, cosineHemispherePdf(wi.z)};
}

}  // namespace invr::diffuse
