// Smooth dielectric interface (glass): Fresnel-weighted choice between delta reflection and
// refraction. wo.z > 0 means wo is outside. Radiance is scaled by 1/eta^2 on refraction.
#pragma once

#include <optional>

#include "core/bsdf/bsdf_sample.h"
#include "core/bsdf/fresnel.h"

namespace invr::dielectric {

inline std::optional<BsdfSample> sample(float ior, Vec3 wo, float uc) {
  float f = fresnelDielectric(wo.z, ior);
  if (uc < f) return BsdfSample{Vec3(-wo.x, -wo.y, wo.z), Rgb(1.f), f, true, false};
  float eta = wo.z > 0.f ? ior : 1.f / ior;  // n_t / n_i
  float sin2T = (1.f - wo.z * wo.z) / (eta * eta);
  float cosT = safeSqrt(1.f - sin2T);
  Vec3 wi(-wo.x / eta, -wo.y / eta, wo.z > 0.f ? -cosT : cosT);
  return BsdfSample{wi, Rgb(1.f / (eta * eta)), 1.f - f, true, true};
}

}  // namespace invr::dielectric
