#include <limits>

#include "core/lights/light.h"

namespace invr {

Vec2 directionToLatLong(Vec3 w) {
  float u = 0.5f + std::atan2(w.x, -w.z) / (2.f * kPi);
  float v = std::acos(clamp(w.y, -1.f, 1.f)) / kPi;
  return {u - std::floor(u), clamp(v, 0.f, 0x1.fffffep-1f)};
}

Vec3 latLongToDirection(Vec2 uv) {
  float phi = (uv.x - 0.5f) * 2.f * kPi, theta = uv.y * kPi;
  float st = std::sin(theta);
  return {st * std::sin(phi), std::cos(theta), -st * std::cos(phi)};
}

// Piecewise-constant lookup, the same density the sampler uses, so eval/pdf stay consistent.
Rgb environmentRadiance(const Light& light, Vec3 w) {
  if (light.kind == LightKind::ConstantEnvironment) return light.radiance * light.scale;
  const Image& im = *light.envImage;
  Vec2 uv = directionToLatLong(w);
  int x = std::min(int(uv.x * float(im.width())), im.width() - 1);
  int y = std::min(int(uv.y * float(im.height())), im.height() - 1);
  return im.rgb(x, y) * light.scale;
}

float environmentPdf(const Light& light, Vec3 w) {
  if (light.kind == LightKind::ConstantEnvironment) return kUniformSpherePdf;
  Vec2 uv = directionToLatLong(w);
  float sinTheta = std::sin(uv.y * kPi);
  if (sinTheta <= 0.f) return 0.f;
  return light.envDistribution.pdf(uv) / (2.f * kPi * kPi * sinTheta);
}

void buildEnvironmentDistribution(Light& light) {
  const Image& im = *light.envImage;
  std::vector<float> w(size_t(im.width()) * im.height());
  for (int y = 0; y < im.height(); ++y) {
    float sinTheta = std::sin(kPi * (float(y) + 0.5f) / float(im.height()));
    for (int x = 0; x < im.width(); ++x) w[size_t(y) * im.width() + x] = std::max(luminance(im.rgb(x, y)), 0.f) * sinTheta;
  }
  light.envDistribution = Distribution2D(w, im.width(), im.height());
}

LightSample environmentSampleAt(const Light& light, Vec3 w) {
  LightSample s;
  s.dist = std::numeric_limits<float>::infinity();
  s.wi = w;
  s.ref.setDirection(w);
  s.pdf = environmentPdf(light, w);
  s.pdfNative = s.pdf;
  s.radiance = environmentRadiance(light, w);
  // Only the constant environment's radiance is a parameter; image maps are not (yet).
  s.emissionPerUnit = light.kind == LightKind::ConstantEnvironment ? light.scale : 0.f;
  return s;
}

LightSample sampleEnvironment(const Light& light, Vec2 u2) {
  if (light.kind == LightKind::ConstantEnvironment) return environmentSampleAt(light, sampleUniformSphere(u2));
  float pdfUv;
  Vec2 uv = light.envDistribution.sample(u2, &pdfUv);
  float sinTheta = std::sin(uv.y * kPi);
  if (sinTheta <= 0.f || pdfUv <= 0.f) {
    LightSample s;
    s.dist = std::numeric_limits<float>::infinity();
    return s;
  }
  LightSample s = environmentSampleAt(light, latLongToDirection(uv));
  s.pdf = pdfUv / (2.f * kPi * kPi * sinTheta);  // exact for this cell (pdf() recomputes the same)
  s.pdfNative = s.pdf;
  return s;
}

}  // namespace invr
