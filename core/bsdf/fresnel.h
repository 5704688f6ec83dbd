// Fresnel reflectance for dielectrics and conductors (unpolarised light).
#pragma once

#include "core/math/vec.h"

namespace invr {

// cosThetaI is measured on the incident side; eta = n_transmitted / n_incident.
// Returns 1 for total internal reflection.
inline float fresnelDielectric(float cosThetaI, float eta) {
  cosThetaI = clamp(cosThetaI, -1.f, 1.f);
  if (cosThetaI < 0.f) { eta = 1.f / eta; cosThetaI = -cosThetaI; }
  float sin2T = (1.f - cosThetaI * cosThetaI) / (eta * eta);
  if (sin2T >= 1.f) return 1.f;
  float cosT = safeSqrt(1.f - sin2T);
  float rPar = (eta * cosThetaI - cosT) / (eta * cosThetaI + cosT);
  float rPerp = (cosThetaI - eta * cosT) / (cosThetaI + eta * cosT);
  return 0.5f * (rPar * rPar + rPerp * rPerp);
}

// Complex index eta + i k, per channel.
inline float fresnelConductor1(float cosI, float eta, float k) {
  cosI = clamp(cosI, 0.f, 1.f);
  float cos2 = cosI * cosI, sin2 = 1.f - cos2;
  float e2 = eta * eta, k2 = k * k;
  float t0 = e2 - k2 - sin2;
  float a2b2 = std::sqrt(std::max(t0 * t0 + 4.f * e2 * k2, 0.f));
  float t1 = a2b2 + cos2;
  float a = safeSqrt(0.5f * (a2b2 + t0));
  float t2 = 2.f * cosI * a;
  float rs = (t1 - t2) / (t1 + t2);
  float t3 = cos2 * a2b2 + sin2 * sin2;
  float t4 = t2 * sin2;
  float rp = rs * (t3 - t4) / (t3 + t4);
  return 0.5f * (rp + rs);
}
inline Rgb fresnelConductor(float cosI, Rgb eta, Rgb k) {
  return {fresnelConductor1(cosI, eta.x, k.x), fresnelConductor1(cosI, eta.y, k.y), fresnelConductor1(cosI, eta.z, k.z)};
}

}  // namespace invr
