// Light sources. One value type with a kind tag; each kind's sampling lives in its own file
// (area_light.cc, point_light.cc, environment_light.cc).
#pragma once

#include <bit>
#include <memory>
#include <string>

#include "core/math/rng.h"
#include "core/math/sampling.h"
#include "core/geometry/mesh.h"
#include "core/image/texture.h"

namespace invr {

enum class LightKind { Area, Point, Spot, Environment, ConstantEnvironment };

// Where a light sample lies, in a form that survives parameter changes: an area-light point is
// (triangle, barycentrics), re-placed on the current mesh; an environment sample is a direction,
// kept bit for bit in the same three fields (16 bytes: stored reservoirs fit one cache line).
struct LightSampleRef {
  uint32_t light = 0;
  uint32_t tri = 0;
  float b1 = 0.f, b2 = 0.f;
  Vec3 direction() const { return Vec3(std::bit_cast<float>(tri), b1, b2); }
  void setDirection(Vec3 d) {
    tri = std::bit_cast<uint32_t>(d.x);
    b1 = d.y;
    b2 = d.z;
  }
};

// A direction towards a light from a reference point. For delta lights `pdf` is 1 and `radiance`
// already includes the 1/d^2 falloff; otherwise pdf is the solid-angle density of wi.
//
// ReSTIR reuses samples across shading points, so resampling works in each light's own measure
// (area on emitters, counting for point lights, solid angle for environments): the integrand in
// that measure is f |cos| Le * jacobian and its density is pdfNative (= pdf * jacobian).
struct LightSample {
  Vec3 wi;
  float dist = 0.f;      // distance to the light point; infinity for environments
  Rgb radiance{0.f};     // arriving at the reference point (before visibility)
  float pdf = 0.f;
  bool delta = false;
  Vec3 lightPoint, lightNormal;  // for area lights (shadow rays, reservoir anchoring)
  float jacobian = 1.f;          // solid angle -> native measure: |cos_l| / d^2 for area lights
  float pdfNative = 0.f;         // density in the native measure (without light selection)
  float emissionPerUnit = 0.f;   // d radiance / d (the light's radiance or intensity), per channel
  LightSampleRef ref;
};
struct Light {
  std::string name;
  LightKind kind = LightKind::Point;
  float scale = 1.f;
  // Area: emissive triangles of one mesh, sampled uniformly by area.
  uint32_t mesh = 0;
  Rgb radiance{0.f};
  bool twoSided = false;
  Distribution1D triangles;
  float area = 0.f;
  // Point and spot.
  Vec3 position, direction;
  Rgb intensity{0.f};
  float cosOuter = -1.f, cosInner = -1.f;
  // Environments (environment: lat-long image with +y up).
  std::shared_ptr<Image> envImage;
  Distribution2D envDistribution;
  // The map turned about +y by this angle: a world direction is looked up at Ry(-angle) w.
  float envCosY = 1.f, envSinY = 0.f;

  bool isDelta() const { return kind == LightKind::Point || kind == LightKind::Spot; }
  bool isInfinite() const { return kind == LightKind::Environment || kind == LightKind::ConstantEnvironment; }
};

// Samples a direction towards `light` (index lightIndex) from point `p` (u2: two uniforms).
// `emitter` is an area light's mesh (with its face normals), null for other lights; the scene's
// overloads (scene.h) pass it.
LightSample sampleLight(const Light& light, const TriangleMesh* emitter, Vec3 p, Vec2 u2, uint32_t lightIndex = 0);
// Re-evaluates a stored light sample of `light` from point p (pdf fields included).
LightSample evalLightSample(const Light& light, const TriangleMesh* emitter, const LightSampleRef& ref, Vec3 p);

// Area lights: emitted radiance leaving point with geometric normal n towards direction w.
inline Rgb areaEmission(const Light& l, Vec3 n, Vec3 w) {
  float c = dot(n, w);
  return (c > 0.f || (l.twoSided && c < 0.f)) ? l.radiance * l.scale : Rgb(0.f);
}
// Solid-angle pdf that sampleLight would assign to hitting point y (normal n) from p.
float areaLightPdf(const Light& light, Vec3 p, Vec3 y, Vec3 n);

// Environments: radiance arriving from direction w, and the sampling pdf of w.
Rgb environmentRadiance(const Light& light, Vec3 w);
float environmentPdf(const Light& light, Vec3 w);
// An image environment's texel (y * width + x) that environmentRadiance(light, w) reads: the one
// the radiance from w is the derivative of (times the light's scale).
int environmentTexel(const Light& light, Vec3 w);
void buildEnvironmentDistribution(Light& light);
Vec2 directionToLatLong(Vec3 w);
Vec3 latLongToDirection(Vec2 uv);

// Spot falloff: 1 inside the inner cone, smoothstep to 0 at the outer cone.
float spotFalloff(const Light& light, Vec3 dirFromLight);

// Power estimate used to choose between lights (luminance of emitted flux; environments use the
// scene's bounding sphere of radius sceneRadius).
float lightPower(const Light& light, float sceneRadius);

}  // namespace invr
