#include "core/lights/light.h"

namespace invr {

float areaLightPdf(const Light& light, Vec3 p, Vec3 y, Vec3 n) {
  Vec3 d = y - p;
  float d2 = lengthSquared(d);
  float cosL = std::abs(dot(n, d)) / std::sqrt(d2);
  if (cosL <= 0.f) return 0.f;
  return d2 / (light.area * cosL);
}

LightSample areaLightSampleAt(const Light& light, const TriangleMesh& m, Vec3 p, uint32_t tri, float b1, float b2) {
  LightSample s;
  Vec3 a = m.positions[m.indices[3 * tri]], b = m.positions[m.indices[3 * tri + 1]], c = m.positions[m.indices[3 * tri + 2]];
  Vec3 y = a * (1.f - b1 - b2) + b * b1 + c * b2;
  Vec3 n = m.faceNormals[tri];
  s.ref.tri = tri;
  s.ref.b1 = b1;
  s.ref.b2 = b2;
  s.lightPoint = y;
  s.lightNormal = n;
  s.pdfNative = 1.f / light.area;
  Vec3 d = y - p;
  float d2 = lengthSquared(d);
  if (!(d2 > 0.f)) return s;
  float dist = std::sqrt(d2);
  s.wi = d / dist;
  s.dist = dist;
  float cosL = std::abs(dot(n, s.wi));
  if (!(cosL > 0.f)) return s;
  s.jacobian = cosL / d2;
  s.pdf = s.pdfNative / s.jacobian;
  s.radiance = areaEmission(light, n, -s.wi);
  s.emissionPerUnit = isBlack(s.radiance) ? 0.f : light.scale;
  return s;
}

LightSample sampleAreaLight(const Light& light, const TriangleMesh& emitter, Vec3 p, Vec2 u2) {
  float remapped;
  size_t tri = light.triangles.sample(u2.x, &remapped);
  // Reuse the remapped first uniform so one light sample costs two dimensions.
  Vec2 bc = sampleUniformTriangle({remapped, u2.y});
  LightSample s = areaLightSampleAt(light, emitter, p, uint32_t(tri), bc.x, bc.y);
  // Uniform by area over the whole emitter: the triangle choice is proportional to its area.
  return s;
}

}  // namespace invr
