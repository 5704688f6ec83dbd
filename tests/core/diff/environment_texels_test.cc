// An image environment map's texels as parameters (lights/<l>/texels): the engine's derivative
// against finite differences of the converged loss for PT, RIS and ReSTIR (direct light) and for
// PT over three bounces, on texels that reach the image in different ways: the sun (through
// the objects' shading, drawn by the map's importance sampling), the zenith (shading and the
// glossy reflection) and one seen directly behind the objects. The reference is the forward
// renderer at theta +- h (tests/core/diff/fd_reference.h).
#include <gtest/gtest.h>

#include "core/diff/diff_scenes.h"
#include "core/diff/fd_reference.h"
#include "core/error.h"
#include "core/lights/light.h"
#include "core/diff/parameter_kind.h"

namespace invr {
namespace {

// A diffuse and a glossy sphere on a diffuse floor under a 16x8 sky with a small sun (behind the
// spheres on the left, 45 degrees high); the camera sees the sky above them. 32x24 pixels.
constexpr const char* kSkyScene = R"({
  "materials": [
    {"name": "clay", "diffuse": {"albedo": {"value": 0.7}}},
    {"name": "gloss", "rough_conductor": {"roughness": {"value": 0.2}}},
    {"name": "floor", "diffuse": {"albedo": {"value": 0.5}}}
  ],
  "shapes": [
    {"name": "clay", "material": "clay", "sphere": {}, "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "translate": {"x": -0.55}}},
    {"name": "gloss", "material": "gloss", "sphere": {}, "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "translate": {"x": 0.55}}},
    {"name": "floor", "material": "floor", "quad": {},
     "transform": {"scale": {"x": 3, "y": 3, "z": 1}, "rotate_xyz_degrees": {"x": -90}, "translate": {"y": -0.5}}}
  ],
  "lights": [{"name": "sky", "environment": {"radiance": {"procedural": {"pattern": "sun_sky", "width": 16, "height": 8,
    "color_a": {"r": 8, "g": 8, "b": 7}, "color_b": {"r": 0.3, "g": 0.4, "b": 0.6}}}}}],
  "views": [{"eye": {"y": 0.3, "z": 3.5}, "target": {"y": 0.1}, "fov_y_degrees": 45}],
  "film": {"width": 32, "height": 24}
})";

using Fixture = test::FdReference;

Fixture& direct() {
  static Fixture f(kSkyScene, {"lights/sky/texels"});
  return f;
}
Fixture& bounces() {
  RenderOptions o;
  o.maxDepth = 3;
  static Fixture f(kSkyScene, {"lights/sky/texels"}, o);
  return f;
}

// The checked components: the sun texel's red, the zenith's green, the blue of a texel seen
// directly above the spheres.
struct Checked {
  size_t sun, zenith, seen;
};
Checked checked(const Fixture& f) {
  const Light& sky = f.scene->lights[0];
  const Image& im = *sky.envImage;
  int sun = 0;
  for (int t = 0; t < im.width() * im.height(); ++t)
    if (luminance(im.rgb(t % im.width(), t / im.width())) > luminance(im.rgb(sun % im.width(), sun / im.width()))) sun = t;
  const size_t zenith = size_t(environmentTexel(sky, Vec3(0.f, 1.f, 0.f)));
  const size_t seen = size_t(environmentTexel(sky, normalize(Vec3(0.f, 0.3f, -1.f))));
  return {3 * size_t(sun), 3 * zenith + 1, 3 * seen + 2};
}

void checkMethod(Fixture& f, GradientMethod method, int maxDepth) {
  GradientOptions o;
  o.method = method;
  o.maxDepth = maxDepth;
  // 16 gradient samples a pixel (ReSTIR 32): the zenith texel's share of a pixel is small, and 4
  // left RIS and ReSTIR above 10 % power at 1024 sessions (ReSTIR at 10.0 % with 16).
  o.sppPrimal = 4;
  o.sppGradient = method == GradientMethod::Restir ? 32 : 16;  // reuse correlates ReSTIR's passes
  const Checked c = checked(f);
  ASSERT_NE(c.sun / 3, c.zenith / 3);
  ASSERT_NE(c.seen / 3, c.zenith / 3);
  std::string label = gradientMethodName(method);
  if (maxDepth > 1) label += " depth " + std::to_string(maxDepth);
  test::expectGradientMatchesFiniteDifferences(f, o, {c.sun, c.zenith, c.seen}, label, [c](size_t k) {
    return std::string(k == c.sun ? "sun texel" : k == c.zenith ? "zenith texel" : "texel seen directly");
  });
}

TEST(EnvironmentTexels, PtMatchesFiniteDifferences) { checkMethod(direct(), GradientMethod::Pt, 1); }
TEST(EnvironmentTexels, RisMatchesFiniteDifferences) { checkMethod(direct(), GradientMethod::Ris, 1); }
// Deep: ReSTIR needs 32 gradient samples a pixel and 1024 sessions for 10 % power (about 140 s).
TEST(EnvironmentTexelsDeep, RestirMatchesFiniteDifferences) { checkMethod(direct(), GradientMethod::Restir, 1); }
TEST(EnvironmentTexels, PtOverThreeBouncesMatchesFiniteDifferences) { checkMethod(bounces(), GradientMethod::Pt, 3); }

// The texels are the map's radiance with its scale applied, round trip; writing them rebuilds
// the sampling distribution (the sun's texel becomes the likeliest direction).
TEST(EnvironmentTexels, ReadWriteRoundTripAndSamplingFollows) {
  auto scene = test::sceneFromJson(kSkyScene);
  ParameterRegistry reg;
  const ParameterSlot& s = reg.add(*scene, "sky.data");  // the Mitsuba name
  EXPECT_EQ(s.name, "sky.data");
  EXPECT_STREQ(s.kind->name(), "environment_texels");
  EXPECT_EQ(s.size, 16u * 8u * 3u);
  EXPECT_EQ(reg.texelsOffset(0), 0);
  std::vector<float> theta = reg.read(*scene);
  const Light& sky = scene->lights[0];
  // Off the poles, where the lat-long density is finite.
  const Vec3 up = normalize(Vec3(0.3f, 0.9f, 0.1f)), down = normalize(Vec3(0.3f, -0.9f, 0.1f));
  const int dark = environmentTexel(sky, down), bright = environmentTexel(sky, up);
  for (int c = 0; c < 3; ++c) theta[size_t(3 * bright + c)] = 500.f;
  reg.write(theta, *scene);
  EXPECT_EQ(reg.read(*scene), theta);
  EXPECT_GT(environmentPdf(sky, up), 100.f * environmentPdf(sky, down));
  EXPECT_FLOAT_EQ(environmentRadiance(sky, up).y, 500.f);
  EXPECT_NE(dark, bright);
}

TEST(EnvironmentTexels, WrongKindsAreRefusedWithTheRightName) {
  auto scene = test::sceneFromJson(kSkyScene);
  ParameterRegistry reg;
  try {
    reg.add(*scene, "lights/sky/intensity");
    FAIL() << "an image map's intensity was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lights/sky/texels"), std::string::npos) << e.what();
  }
  auto diff = test::sceneFromJson(test::kDiffScene);
  try {
    reg.add(*diff, "lights/lamp/texels");
    FAIL() << "an area light's texels were accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lights/lamp/intensity"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace invr
