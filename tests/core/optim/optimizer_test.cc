#include "core/optim/optimizer.h"

#include <gtest/gtest.h>

#include "core/error.h"
#include "test_util.h"

namespace invr {
namespace {

constexpr const char* kScene = R"({
  "materials": [{"name": "m", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}},
                {"name": "g", "rough_plastic": {"roughness": {"value": 0.4}}}],
  "shapes": [{"name": "q", "material": "m", "quad": {}}, {"name": "p", "material": "g", "box": {}}],
  "lights": [{"name": "l", "point": {"position": {"z": 2}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 3}, "target": {}}]
})";

// One parameter of the scene above at a given learning rate, starting from the scene's value.
struct Registered {
  decltype(test::sceneFromJson(kScene)) scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  std::vector<float> theta;
  Registered(const char* name, float learningRate) {
    ParameterOptions o;
    o.learningRate = learningRate;
    reg.add(*scene, name, o);
    theta = reg.read(*scene);
  }
};

TEST(Optimizer, AdamConvergesOnAQuadraticAndRespectsBounds) {
  Registered r("materials/m/albedo", 0.05f);
  const ParameterRegistry& reg = r.reg;
  std::vector<float>& theta = r.theta;
  const float target[3] = {0.2f, 0.9f, 1.7f};  // the last is outside [0, 1]: must stop at 1
  OptimizerState st;
  for (int i = 0; i < 400; ++i) {
    std::vector<double> g(3);
    for (int c = 0; c < 3; ++c) g[size_t(c)] = 2.0 * (theta[size_t(c)] - target[c]);
    optimizerStep(OptimizerKind::Adam, reg, g, theta, st);
  }
  EXPECT_NEAR(theta[0], 0.2f, 0.01f);
  EXPECT_NEAR(theta[1], 0.9f, 0.01f);
  EXPECT_EQ(theta[2], 1.f);
  EXPECT_EQ(st.step, 400u);
}

TEST(Optimizer, SgdTakesExactSteps) {
  Registered r("materials/g/roughness", 0.1f);
  const ParameterRegistry& reg = r.reg;
  std::vector<float>& theta = r.theta;
  ASSERT_EQ(theta.size(), 1u);
  EXPECT_FLOAT_EQ(theta[0], 0.4f);
  OptimizerState st;
  optimizerStep(OptimizerKind::Sgd, reg, {1.0}, theta, st);
  EXPECT_FLOAT_EQ(theta[0], 0.3f);
  optimizerStep(OptimizerKind::Sgd, reg, {100.0}, theta, st);
  EXPECT_FLOAT_EQ(theta[0], 0.01f);  // roughness lower bound
}

TEST(Optimizer, LearningRatesDecayWithTheirHalfLife) {
  Registered r("materials/g/roughness", 0.1f);
  const ParameterRegistry& reg = r.reg;
  std::vector<float>& theta = r.theta;
  OptimizerState st;
  const LearningRateSchedule halfLife2{2.0};
  // Steps of lr * 2 / (2 + t): 0.1, 0.0667, 0.05 for t = 0, 1, 2.
  optimizerStep(OptimizerKind::Sgd, reg, {1.0}, theta, st, halfLife2);
  EXPECT_FLOAT_EQ(theta[0], 0.3f);
  optimizerStep(OptimizerKind::Sgd, reg, {1.0}, theta, st, halfLife2);
  EXPECT_NEAR(theta[0], 0.3f - 0.1f * 2.f / 3.f, 1e-6f);
  optimizerStep(OptimizerKind::Sgd, reg, {1.0}, theta, st, halfLife2);
  EXPECT_NEAR(theta[0], 0.3f - 0.1f * 2.f / 3.f - 0.05f, 1e-6f);
  EXPECT_EQ(LearningRateSchedule{}.factor(1000), 1.0);  // 0: constant
  // Adam's step is the rate times a ratio of moments: a constant gradient moves by exactly the rate.
  std::vector<float> a = reg.read(*r.scene);
  OptimizerState sa;
  optimizerStep(OptimizerKind::Adam, reg, {1.0}, a, sa, LearningRateSchedule{1.0});
  optimizerStep(OptimizerKind::Adam, reg, {1.0}, a, sa, LearningRateSchedule{1.0});
  EXPECT_NEAR(a[0], 0.4f - 0.1f - 0.05f, 1e-5f);
}

TEST(Parameters, NamesResolveOrFailClearly) {
  auto scene = test::sceneFromJson(kScene);
  ParameterRegistry reg;
  EXPECT_EQ(reg.add(*scene, "lights/l/intensity").size, 3u);
  auto err = [&](const std::string& name) {
    try {
      reg.add(*scene, name);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(err("materials/nope/albedo").find("no material named 'nope'"), std::string::npos);
  EXPECT_NE(err("materials/m/roughness").find("has no roughness"), std::string::npos);
  EXPECT_NE(err("materials/m/shininess").find("unknown material property"), std::string::npos);
  EXPECT_NE(err("lights/l/intensity").find("listed twice"), std::string::npos);
  EXPECT_NE(err("lights/zz/intensity").find("no light named"), std::string::npos);
  EXPECT_NE(err("films/a/size").find("unknown parameter group"), std::string::npos);
  EXPECT_NE(err("cameras/0/fov").find("unknown camera property"), std::string::npos);
  ParameterOptions inverted;
  inverted.lower = 1.f;
  inverted.upper = 0.f;
  EXPECT_THROW(reg.add(*scene, "materials/m/albedo", inverted), InputError);
}

TEST(Parameters, WriteThenReadRoundTripsThroughTextures) {
  auto scene = test::sceneFromJson(R"({
    "materials": [{"name": "t", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 8}, "scale": 0.5}}}],
    "shapes": [{"name": "q", "material": "t", "quad": {}}],
    "lights": [{"name": "l", "point": {"position": {"z": 2}, "intensity": {"r": 1}}}],
    "views": [{"eye": {"z": 3}, "target": {}}]})");
  ParameterRegistry reg;
  const auto& slot = reg.add(*scene, "materials/t/albedo");
  EXPECT_EQ(slot.size, 8u * 8u * 3u);
  std::vector<float> theta(reg.size());
  for (size_t i = 0; i < theta.size(); ++i) theta[i] = float(i % 7) / 10.f;
  reg.write(theta, *scene);
  auto back = reg.read(*scene);
  for (size_t i = 0; i < theta.size(); ++i) EXPECT_NEAR(back[i], theta[i], 1e-6f);
  EXPECT_THROW(reg.write(std::vector<float>(5), *scene), InputError);
}

}  // namespace
}  // namespace invr
