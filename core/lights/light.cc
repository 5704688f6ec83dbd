#include "core/lights/light.h"

#include <stdexcept>

namespace invr {

LightSample sampleAreaLight(const Light& light, const TriangleMesh& emitter, Vec3 p, Vec2 u2);
LightSample areaLightSampleAt(const Light& light, const TriangleMesh& emitter, Vec3 p, uint32_t tri, float b1, float b2);
LightSample samplePointOrSpot(const Light& light, Vec3 p);
LightSample sampleEnvironment(const Light& light, Vec2 u2);
LightSample environmentSampleAt(const Light& light, Vec3 w);

namespace {

// Each kind's sample, returned straight into the caller's object (assigning a call's result to a
// declared sample would build it elsewhere and copy it: 88 bytes per light sample).
LightSample sampleOfKind(const Light& light, const TriangleMesh* emitter, Vec3 p, Vec2 u2) {
  switch (light.kind) {
    case LightKind::Area:
      if (!emitter) throw std::logic_error("sampleLight: an area light needs its emitter mesh");
      return sampleAreaLight(light, *emitter, p, u2);
    case LightKind::Point:
    case LightKind::Spot: return samplePointOrSpot(light, p);
    default: return sampleEnvironment(light, u2);
  }
}

LightSample evalOfKind(const Light& light, const TriangleMesh* emitter, const LightSampleRef& ref, Vec3 p) {
  switch (light.kind) {
    case LightKind::Area:
      if (!emitter) throw std::logic_error("evalLightSample: an area light needs its emitter mesh");
      return areaLightSampleAt(light, *emitter, p, ref.tri, ref.b1, ref.b2);
    case LightKind::Point:
    case LightKind::Spot: return samplePointOrSpot(light, p);
    default: return environmentSampleAt(light, ref.direction());
  }
}

}  // namespace

LightSample sampleLight(const Light& light, const TriangleMesh* emitter, Vec3 p, Vec2 u2, uint32_t lightIndex) {
  LightSample s = sampleOfKind(light, emitter, p, u2);
  s.ref.light = lightIndex;
  return s;
}

LightSample evalLightSample(const Light& light, const TriangleMesh* emitter, const LightSampleRef& ref, Vec3 p) {
  LightSample s = evalOfKind(light, emitter, ref, p);
  s.ref = ref;
  return s;
}

float lightPower(const Light& light, float sceneRadius) {
  switch (light.kind) {
    case LightKind::Area: return luminance(light.radiance) * light.scale * light.area * kPi * (light.twoSided ? 2.f : 1.f);
    case LightKind::Point: return luminance(light.intensity) * light.scale * 4.f * kPi;
    case LightKind::Spot:
      return luminance(light.intensity) * light.scale * 2.f * kPi * (1.f - 0.5f * (light.cosInner + light.cosOuter));
    case LightKind::ConstantEnvironment:
      return luminance(light.radiance) * light.scale * 4.f * kPi * kPi * sceneRadius * sceneRadius;
    case LightKind::Environment: {
      // Mean radiance over the sphere (solid-angle weighted) times the flux through the disk.
      const Image& im = *light.envImage;
      double sum = 0, wsum = 0;
      for (int y = 0; y < im.height(); ++y) {
        double s = std::sin(kPi * (y + 0.5) / im.height());
        for (int x = 0; x < im.width(); ++x) { sum += s * luminance(im.rgb(x, y)); wsum += s; }
      }
      return float(sum / wsum) * light.scale * 4.f * kPi * kPi * sceneRadius * sceneRadius;
    }
  }
  return 0.f;
}

}  // namespace invr
