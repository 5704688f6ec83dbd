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

namespace {

// Lat-long coordinates of world direction w on the (possibly rotated) map, and the inverse.
Vec2 mapUv(const Light& l, Vec3 w) {
  return directionToLatLong({l.envCosY * w.x - l.envSinY * w.z, w.y, l.envSinY * w.x + l.envCosY * w.z});
}
Vec3 mapDirection(const Light& l, Vec2 uv) {
  Vec3 d = latLongToDirection(uv);
  return {l.envCosY * d.x + l.envSinY * d.z, d.y, -l.envSinY * d.x + l.envCosY * d.z};
}

// The texel at lat-long coordinates uv: piecewise-constant lookup, the same cells the sampler
// uses, so eval and pdf stay consistent (and a direction's radiance is one texel's, whose
// derivative is the light's scale).
int mapTexel(const Image& im, Vec2 uv) {
  int x = std::min(int(uv.x * float(im.width())), im.width() - 1);
  int y = std::min(int(uv.y * float(im.height())), im.height() - 1);
  return y * im.width() + x;
}

Rgb mapRadiance(const Light& light, Vec2 uv) {
  const Image& im = *light.envImage;
  const int t = mapTexel(im, uv);
  return im.rgb(t % im.width(), t / im.width()) * light.scale;
}

float mapPdf(const Light& light, Vec2 uv) {
  float sinTheta = std::sin(uv.y * kPi);
  if (sinTheta <= 0.f) return 0.f;
  return light.envDistribution.pdf(uv) / (2.f * kPi * kPi * sinTheta);
}

// A sample towards w whose lat-long coordinates are uv (= directionToLatLong(w)) and density pdf.
LightSample mapSample(const Light& light, Vec3 w, Vec2 uv, float pdf) {
  LightSample s;
  s.dist = std::numeric_limits<float>::infinity();
  s.wi = w;
  s.ref.setDirection(w);
  s.pdf = pdf;
  s.pdfNative = pdf;
  s.radiance = mapRadiance(light, uv);
  s.emissionPerUnit = light.scale;  // per unit of the texel looked up (lights/<env>/texels)
  return s;
}

}  // namespace

Rgb environmentRadiance(const Light& light, Vec3 w) {
  if (light.kind == LightKind::ConstantEnvironment) return light.radiance * light.scale;
  return mapRadiance(light, mapUv(light, w));
}

int environmentTexel(const Light& light, Vec3 w) { return mapTexel(*light.envImage, mapUv(light, w)); }

float environmentPdf(const Light& light, Vec3 w) {
  if (light.kind == LightKind::ConstantEnvironment) return kUniformSpherePdf;
  return mapPdf(light, mapUv(light, w));
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
  if (light.kind != LightKind::ConstantEnvironment) {
    const Vec2 uv = mapUv(light, w);  // once, for both the pdf and the radiance
    return mapSample(light, w, uv, mapPdf(light, uv));
  }
  LightSample s;
  s.dist = std::numeric_limits<float>::infinity();
  s.wi = w;
  s.ref.setDirection(w);
  s.pdf = kUniformSpherePdf;
  s.pdfNative = s.pdf;
  s.radiance = light.radiance * light.scale;
  s.emissionPerUnit = light.scale;  // the constant environment's radiance is a parameter
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
  const Vec3 w = mapDirection(light, uv);
  // The density is exact for the sampled cell (pdf() recomputes the same); the radiance is looked
  // up where every other evaluation at w looks it up.
  return mapSample(light, w, mapUv(light, w), pdfUv / (2.f * kPi * kPi * sinTheta));
}

}  // namespace invr
