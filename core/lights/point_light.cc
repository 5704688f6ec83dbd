#include "core/lights/light.h"

namespace invr {

float spotFalloff(const Light& light, Vec3 dirFromLight) {
  float c = dot(dirFromLight, light.direction);
  if (c >= light.cosInner) return 1.f;
  if (c <= light.cosOuter) return 0.f;
  float t = (c - light.cosOuter) / (light.cosInner - light.cosOuter);
  return t * t * (3.f - 2.f * t);
}

LightSample samplePointOrSpot(const Light& light, Vec3 p) {
  LightSample s;
  Vec3 d = light.position - p;
  float d2 = lengthSquared(d);
  if (d2 <= 0.f) return s;
  s.dist = std::sqrt(d2);
  s.wi = d / s.dist;
  s.pdf = 1.f;
  s.pdfNative = 1.f;
  s.delta = true;
  s.lightPoint = light.position;
  float factor = light.scale / d2;
  if (light.kind == LightKind::Spot) factor *= spotFalloff(light, -s.wi);
  s.radiance = light.intensity * factor;
  s.emissionPerUnit = factor;
  return s;
}

}  // namespace invr
