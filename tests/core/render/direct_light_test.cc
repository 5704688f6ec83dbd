// Direct illumination against analytic references: a point light over a diffuse plane, a square
// area light over a point (form factor), and RIS against plain NEE on scenes with many lights.
#include <gtest/gtest.h>

#include "core/render/path_tracer.h"
#include "core/scene/zoo.h"
#include "test_util.h"

namespace invr {
namespace {

constexpr const char* kPointLightScene = R"({
  "materials": [{"name": "plane", "diffuse": {"albedo": {"value": 0.5}}}],
  "shapes": [{"name": "plane", "material": "plane", "quad": {},
              "transform": {"scale": {"x": 10, "y": 10, "z": 1}, "rotate_xyz_degrees": {"x": -90}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0, "y": 2, "z": 0}, "intensity": {"r": 3, "g": 3, "b": 3}}}],
  "views": [{"eye": {"y": 5}, "target": {}, "up": {"z": -1}}]
})";

TEST(DirectLight, PointLightOverDiffusePlaneIsAnalytic) {
  auto scene = test::sceneFromJson(kPointLightScene);
  for (auto est : {LightEstimator::NeeMis, LightEstimator::Ris}) {
    RenderOptions opt;
    opt.estimator = est;
    for (Vec3 p : {Vec3(0.3f, 0, 0.2f), Vec3(-1.5f, 0, 0.7f), Vec3(2.5f, 0, -3.f)}) {
      Sampler s(RngKey{1});
      Rgb L = pathRadiance(*scene, p + Vec3(0, 1, 0), Vec3(0, -1, 0), s, opt);
      // L = rho / pi * I * cos(theta) / r^2 with cos(theta) = h / r.
      double r2 = p.x * p.x + 4.0 + p.z * p.z, r = std::sqrt(r2);
      double expected = 0.5 / M_PI * 3.0 * (2.0 / r) / r2;
      EXPECT_NEAR(L.x, expected, 1e-5 * expected + 1e-7);
    }
  }
}

// Square light of half-side a at height h above the shading point, facing it.
constexpr const char* kAreaLightScene = R"({
  "materials": [{"name": "plane", "diffuse": {"albedo": {"value": 0.6}}},
                {"name": "lamp", "diffuse": {"albedo": {"value": 0}}}],
  "shapes": [{"name": "plane", "material": "plane", "quad": {},
              "transform": {"scale": {"x": 10, "y": 10, "z": 1}, "rotate_xyz_degrees": {"x": -90}}},
             {"name": "lamp", "material": "lamp", "quad": {},
              "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"x": 90}, "translate": {"y": 1}}}],
  "lights": [{"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 2, "g": 2, "b": 2}}}],
  "views": [{"eye": {"y": 5}, "target": {}, "up": {"z": -1}}]
})";

// Differential form factor from a point to a parallel rectangle a x b whose corner is above the
// point at distance c.
double cornerFormFactor(double a, double b, double c) {
  double X = a / c, Y = b / c;
  double sx = std::sqrt(1 + X * X), sy = std::sqrt(1 + Y * Y);
  return (X / sx * std::atan(Y / sx) + Y / sy * std::atan(X / sy)) / (2 * M_PI);
}

TEST(DirectLight, SquareAreaLightMatchesFormFactor) {
  auto scene = test::sceneFromJson(kAreaLightScene);
  // Point below the centre: four corner rectangles of 0.5 x 0.5 at distance 1.
  double F = 4 * cornerFormFactor(0.5, 0.5, 1.0);
  double expected = 0.6 * 2.0 * F;  // L_o = rho * L_e * F
  struct Variant { LightEstimator est; bool vis; const char* name; };
  for (auto v : {Variant{LightEstimator::NeeMis, false, "nee_mis"}, Variant{LightEstimator::Ris, false, "ris"},
                 Variant{LightEstimator::Ris, true, "ris_visibility"}}) {
    RenderOptions opt;
    opt.estimator = v.est;
    opt.risVisibilityInTarget = v.vis;
    opt.risCandidates = 4;
    test::MeanSE m;
    for (int i = 0; i < 40000; ++i) {
      Sampler s(RngKey{2, 0, 0, 0, uint64_t(i)});
      m.add(pathRadiance(*scene, Vec3(0, 0.5f, 0), Vec3(0, -1, 0), s, opt).x);
    }
    m.mean *= test::mutation();
    EXPECT_NEAR(m.mean, expected, test::kSigmas * m.se()) << v.name << " se " << m.se();
    test::expectPower(v.name, m.se(), expected);
  }
}

// RIS must be unbiased against plain NEE + MIS: compare the mean luminance over a pixel set.
void compareRisWithNee(const std::string& zooName, int maxDepth) {
  auto scene = buildScene(zooScene(zooName));
  const Camera& cam = scene->cameras[0];
  auto run = [&](RenderOptions opt) {
    test::MeanSE m;
    for (int py = 4; py < scene->height; py += 8)
      for (int px = 4; px < scene->width; px += 8)
        for (int s = 0; s < 512; ++s) {
          Sampler sampler(RngKey{opt.seed, 0, 0, uint64_t(py * scene->width + px), uint64_t(s)});
          float fx = px + sampler.next1D(), fy = py + sampler.next1D();
          m.add(luminance(pathRadiance(*scene, cam.eye, cam.direction(fx, fy, scene->width, scene->height), sampler, opt)));
        }
    return m;
  };
  RenderOptions nee;
  nee.maxDepth = maxDepth;
  nee.seed = 100;
  auto mNee = run(nee);
  for (bool vis : {false, true}) {
    RenderOptions ris = nee;
    ris.estimator = LightEstimator::Ris;
    ris.risCandidates = 8;
    ris.risVisibilityInTarget = vis;
    ris.seed = 200;
    auto mRis = run(ris);
    double se = std::sqrt(mNee.se() * mNee.se() + mRis.se() * mRis.se());
    EXPECT_NEAR(mRis.mean * test::mutation(), mNee.mean, test::kSigmas * se) << zooName << " visibility " << vis;
    test::expectPower(zooName + (vis ? ", RIS with visibility" : ", RIS") + " against NEE", se, mNee.mean);
  }
}

TEST(DirectLight, RisUnbiasedAgainstNeeOnPointAndSpotLights) { compareRisWithNee("oxalis", 1); }
TEST(DirectLight, RisUnbiasedAgainstNeeOnAreaLightsWithBounces) { compareRisWithNee("cornell", 3); }
TEST(DirectLight, RisUnbiasedAgainstNeeOnEnvironmentAndSpot) { compareRisWithNee("spot", 1); }

}  // namespace
}  // namespace invr
