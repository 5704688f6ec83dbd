#include "core/lights/light.h"
#include "core/scene/scene.h"

namespace invr {

float areaLightPdf(const Light& light, Vec3 p, Vec3 y, Vec3 n) {
  Vec3 d = y - p;
  float d2 = lengthSquared(d);
  float cosL = std::abs(dot(n, d)) / std::sqrt(d2);
  if (cosL <= 0.f) return 0.f;
  return d2 / (light.area * cosL);
}

LightSample sampleAreaLight(const Light& light, const Scene& scene, Vec3 p, Vec2 u2) {
  LightSample s;
  float remapped;
  size_t tri = light.triangles.sample(u2.x, &remapped);
  const TriangleMesh& m = scene.meshes[light.mesh];
  Vec3 a = m.positions[m.indices[3 * tri]], b = m.positions[m.indices[3 * tri + 1]], c = m.positions[m.indices[3 * tri + 2]];
  // Reuse the remapped first uniform so one light sample costs two dimensions.
  Vec2 bc = sampleUniformTriangle({remapped, u2.y});
  Vec3 y = a * (1.f - bc.x - bc.y) + b * bc.x + c * bc.y;
  Vec3 n = scene.faceNormal(light.mesh, uint32_t(tri));
  Vec3 d = y - p;
  float d2 = lengthSquared(d);
  if (d2 <= 0.f) return s;
  float dist = std::sqrt(d2);
  s.wi = d / dist;
  s.dist = dist;
  s.lightPoint = y;
  s.lightNormal = n;
  float cosL = std::abs(dot(n, s.wi));
  if (cosL <= 0.f) return s;
  s.pdf = d2 / (light.area * cosL);
  s.radiance = areaEmission(light, n, -s.wi);
  return s;
}

}  // namespace invr
