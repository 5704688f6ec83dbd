// Isotropic GGX (Trowbridge-Reitz) distribution with Smith shadowing and visible-normal sampling
// (Heitz 2018). All vectors in the local shading frame (z = normal); alpha is GGX roughness.
#pragma once

#include "core/math/vec.h"

namespace invr::ggx {

inline float D(Vec3 m, float alpha) {
  if (m.z <= 0.f) return 0.f;
  float a2 = alpha * alpha;
  float t = m.z * m.z * (a2 - 1.f) + 1.f;
  return a2 / (kPi * t * t);
}

inline float lambda(Vec3 w, float alpha) {
  float cos2 = w.z * w.z;
  if (cos2 <= 0.f) return 0.f;
  float tan2 = std::max(0.f, 1.f - cos2) / cos2;
  return 0.5f * (-1.f + std::sqrt(1.f + alpha * alpha * tan2));
}

// Adjoint of D with respect to alpha.
inline float dD_dAlpha(Vec3 m, float alpha) {
  if (m.z <= 0.f) return 0.f;
  float a2 = alpha * alpha, c2 = m.z * m.z;
  float t = c2 * (a2 - 1.f) + 1.f;
  return 2.f * alpha / (kPi * t * t) * (1.f - 2.f * a2 * c2 / t);
}

// Adjoint of lambda with respect to alpha.
inline float dLambda_dAlpha(Vec3 w, float alpha) {
  float cos2 = w.z * w.z;
  if (cos2 <= 0.f) return 0.f;
  float tan2 = std::max(0.f, 1.f - cos2) / cos2;
  return 0.5f * alpha * tan2 / std::sqrt(1.f + alpha * alpha * tan2);
}

inline float G1(Vec3 w, float alpha) { return 1.f / (1.f + lambda(w, alpha)); }
inline float G2(Vec3 wo, Vec3 wi, float alpha) { return 1.f / (1.f + lambda(wo, alpha) + lambda(wi, alpha)); }
inline float dG2_dAlpha(Vec3 wo, Vec3 wi, float alpha) {
  float g = G2(wo, wi, alpha);
  return -g * g * (dLambda_dAlpha(wo, alpha) + dLambda_dAlpha(wi, alpha));
}
// d/dalpha of D(m) G2(wo, wi): the roughness dependence shared by every GGX lobe.
inline float dDG2_dAlpha(Vec3 m, Vec3 wo, Vec3 wi, float alpha) {
  return dD_dAlpha(m, alpha) * G2(wo, wi, alpha) + D(m, alpha) * dG2_dAlpha(wo, wi, alpha);
}

// Density of visible normals seen from wo (wo.z > 0), with respect to solid angle of m.
inline float pdfVisible(Vec3 wo, Vec3 m, float alpha) {
  float dm = dot(wo, m);
  if (dm <= 0.f || wo.z <= 0.f) return 0.f;
  return G1(wo, alpha) * dm * D(m, alpha) / wo.z;
}

inline Vec3 sampleVisible(Vec3 wo, float alpha, Vec2 u) {
  Vec3 vh = normalize(Vec3(alpha * wo.x, alpha * wo.y, wo.z));
  float lensq = vh.x * vh.x + vh.y * vh.y;
  Vec3 t1 = lensq > 0.f ? Vec3(-vh.y, vh.x, 0.f) / std::sqrt(lensq) : Vec3(1.f, 0.f, 0.f);
  Vec3 t2 = cross(vh, t1);
  float r = std::sqrt(u.x), phi = 2.f * kPi * u.y;
  float p1 = r * std::cos(phi), p2 = r * std::sin(phi);
  float s = 0.5f * (1.f + vh.z);
  p2 = (1.f - s) * safeSqrt(1.f - p1 * p1) + s * p2;
  Vec3 nh = t1 * p1 + t2 * p2 + vh * safeSqrt(1.f - p1 * p1 - p2 * p2);
  return normalize(Vec3(alpha * nh.x, alpha * nh.y, std::max(1e-7f, nh.z)));
}

// Density of the reflected direction wi when m is drawn with sampleVisible.
inline float pdfReflect(Vec3 wo, Vec3 wi, float alpha) {
  Vec3 h = wo + wi;
  if (lengthSquared(h) == 0.f) return 0.f;
  Vec3 m = normalize(h);
  float dm = dot(wo, m);
  if (dm <= 0.f) return 0.f;
  return pdfVisible(wo, m, alpha) / (4.f * dm);
}

// Adjoint of pdfReflect with respect to alpha (the variance estimators differentiate sampling
// densities, Yan et al. 2024 §4.2). pdfReflect = G1(wo) D(m) / (4 wo.z): dot(wo, m) cancels.
// Defined over the whole sphere of wi, like pdfReflect (reflections below the horizon included).
inline float dPdfReflect_dAlpha(Vec3 wo, Vec3 wi, float alpha) {
  Vec3 h = wo + wi;
  if (lengthSquared(h) == 0.f || wo.z <= 0.f) return 0.f;
  Vec3 m = normalize(h);
  if (dot(wo, m) <= 0.f) return 0.f;
  float g1 = G1(wo, alpha);
  float dG1 = -g1 * g1 * dLambda_dAlpha(wo, alpha);
  return (dG1 * D(m, alpha) + g1 * dD_dAlpha(m, alpha)) / (4.f * wo.z);
}

inline Vec3 reflect(Vec3 w, Vec3 m) { return m * (2.f * dot(w, m)) - w; }

}  // namespace invr::ggx
