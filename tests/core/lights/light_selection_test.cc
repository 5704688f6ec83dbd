// Light-selection probabilities and their adjoints against central differences: the softmax rule
// (logits) and selection by power (intensities), on a scene with an area, a point, a spot and a
// constant-environment light. Deterministic: relative 1e-3. The pmfs are floats, so the
// differences use h = 5 % and Richardson extrapolation (truncation O(h^4), rounding ~1e-5).
#include "core/lights/light_selection.h"

#include <gtest/gtest.h>

#include "test_util.h"

namespace invr {
namespace {

constexpr const char* kLights = R"({
  "materials": [{"name": "m", "diffuse": {"albedo": {"value": 0.5}}}],
  "shapes": [
    {"name": "floor", "material": "m", "quad": {}, "transform": {"scale": {"x": 2, "y": 2, "z": 1}}},
    {"name": "lamp", "material": "m", "quad": {}, "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "translate": {"z": 1}}}
  ],
  "lights": [
    {"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 5, "g": 4, "b": 3}}},
    {"name": "bulb", "point": {"position": {"z": 2}, "intensity": {"r": 2, "g": 2.5, "b": 1}}},
    {"name": "spot", "spot": {"position": {"x": 1, "z": 2}, "target": {"x": 1}, "intensity": {"r": 3, "g": 1, "b": 1}}},
    {"name": "sky", "constant_environment": {"radiance": {"r": 0.1, "g": 0.1, "b": 0.2}}}
  ],
  "views": [{"eye": {"z": 3}, "target": {}}],
  "film": {"width": 8, "height": 8}
})";

TEST(LightSelection, SoftmaxLogPmfAdjoint) {
  const std::vector<float> logits = {0.3f, -1.2f, 2.0f, 0.1f};
  const std::vector<double> coef = {0.7, -0.4, 1.3, 0.25};
  std::vector<double> g(4, 0.0);
  addSoftmaxLogPmfAdjoint(softmax(logits), coef, g);
  for (size_t k = 0; k < 4; ++k) {
    auto objective = [&](float dz) {
      std::vector<float> z = logits;
      z[k] += dz;
      auto p = softmax(z);
      double s = 0;
      for (size_t i = 0; i < 4; ++i) s += coef[i] * std::log(double(p[i]));
      return s;
    };
    const float h = 1e-3f;
    double fd = (objective(h) - objective(-h)) / (2.0 * h);
    EXPECT_NEAR(g[k], fd, 1e-3 * std::max(1.0, std::abs(fd))) << "logit " << k;
  }
}

TEST(LightSelection, PowerLogPmfAdjointForEveryLightKind) {
  auto scene = test::sceneFromJson(kLights);
  const std::vector<double> coef = {0.9, -0.5, 0.6, 1.1};
  double coefSum = 0;
  for (double c : coef) coefSum += c;
  auto value = [](Light& l) -> Rgb& { return (l.kind == LightKind::Point || l.kind == LightKind::Spot) ? l.intensity : l.radiance; };
  for (size_t k = 0; k < scene->lights.size(); ++k) {
    scene->updateLightSelection();
    Rgb g = powerLogPmfAdjoint(scene->lights[k], scene->radius, scene->selectionPower(k), scene->selectionPowerTotal(), coef[k], coefSum);
    for (int c = 0; c < 3; ++c) {
      auto objective = [&](float dv) {
        Rgb saved = value(scene->lights[k]);
        value(scene->lights[k])[c] += dv;
        scene->updateLightSelection();
        double s = 0;
        for (size_t i = 0; i < scene->lights.size(); ++i) s += coef[i] * std::log(double(scene->lightSelection().pmf(i)));
        value(scene->lights[k]) = saved;
        return s;
      };
      const float h = 0.05f * value(scene->lights[k])[c];
      auto central = [&](float d) { return (objective(d) - objective(-d)) / (2.0 * d); };
      double fd = (4.0 * central(0.5f * h) - central(h)) / 3.0;
      EXPECT_NEAR(g[c], fd, 1e-3 * std::max(std::abs(fd), 1e-2 * std::abs(double(g[0]) + g[1] + g[2]) + 1e-6))
          << scene->lights[k].name << " channel " << c;
    }
  }
}

}  // namespace
}  // namespace invr
