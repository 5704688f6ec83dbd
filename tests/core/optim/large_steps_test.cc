#include "core/optim/large_steps.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/diff/parameters.h"
#include "core/optim/optimizer.h"
#include "test_util.h"

namespace invr {
namespace {

// An n x n grid of vertices with its edges (right, down and one diagonal per cell).
std::vector<std::pair<uint32_t, uint32_t>> gridEdges(uint32_t n) {
  std::vector<std::pair<uint32_t, uint32_t>> e;
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const uint32_t v = y * n + x;
      if (x + 1 < n) e.emplace_back(v, v + 1);
      if (y + 1 < n) e.emplace_back(v, v + n);
      if (x + 1 < n && y + 1 < n) e.emplace_back(v, v + n + 1);
    }
  return e;
}

std::vector<double> pseudoRandom(size_t n, uint32_t seed) {
  std::vector<double> v(n);
  uint32_t s = seed * 747796405u + 2891336453u;
  for (double& x : v) {
    s = s * 1664525u + 1013904223u;
    x = double(s >> 8) / double(1u << 24) * 2.0 - 1.0;
  }
  return v;
}

TEST(LargeSteps, SolveInvertsTheParametrisation) {
  const uint32_t n = 20;
  for (double lambda : {0.0, 1.0, 19.0, 500.0}) {
    LargeSteps ls(n * n, gridEdges(n), lambda);
    const std::vector<double> x = pseudoRandom(3 * n * n, 1);
    const std::vector<double> back = ls.solve(ls.toU(x));
    double worst = 0;
    for (size_t i = 0; i < x.size(); ++i) worst = std::max(worst, std::abs(back[i] - x[i]));
    EXPECT_LT(worst, 1e-6) << "lambda " << lambda;
  }
  EXPECT_THROW(LargeSteps(4, {{0, 1}}, -1.0), std::invalid_argument);
}

// The zoo-style quad scene's plane as a vertex parameter (4 vertices, 5 edges).
const char* kQuad = R"({"materials": [{"name": "m", "diffuse": {}}],
  "shapes": [{"name": "plane", "quad": {}, "material": "m"}],
  "lights": [{"name": "bulb", "point": {"position": {"z": 3}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 4}, "target": {}}], "film": {"width": 8, "height": 8}})";

// lambda = 0 is plain Adam, bit for bit: the update written out here as Adam defines it.
TEST(LargeSteps, LambdaZeroIsPlainAdamBitForBit) {
  auto scene = test::sceneFromJson(kQuad);
  ParameterRegistry reg;
  ParameterOptions o;
  o.largeStepsLambda = 0.f;
  reg.add(*scene, "shapes/plane/vertices", o);
  std::vector<float> theta = reg.read(*scene), expected = theta;
  OptimizerState st;
  std::vector<double> m(theta.size(), 0.0), v(theta.size(), 0.0);
  const AdamSettings a;
  const double lr = reg.slots()[0].learningRate;
  for (int step = 1; step <= 5; ++step) {
    const std::vector<double> g = pseudoRandom(theta.size(), uint32_t(step));
    optimizerStep(OptimizerKind::Adam, reg, g, theta, st);
    const double c1 = 1.0 - std::pow(a.beta1, double(step)), c2 = 1.0 - std::pow(a.beta2, double(step));
    for (size_t i = 0; i < theta.size(); ++i) {
      m[i] = a.beta1 * m[i] + (1 - a.beta1) * g[i];
      v[i] = a.beta2 * v[i] + (1 - a.beta2) * g[i] * g[i];
      const double s = 1.0 * lr * (m[i] / c1) / (std::sqrt(v[i] / c2) + a.epsilon);
      expected[i] = float(double(expected[i]) - s);
    }
    for (size_t i = 0; i < theta.size(); ++i) ASSERT_EQ(theta[i], expected[i]) << "step " << step << " value " << i;
  }
}

// With lambda > 0, an SGD step moves u = M x by -lr M^-1 g, so x moves by -lr M^-2 g: applying M
// twice (a product, not the solve under test) to the move gives back -lr g. The move is read from
// float theta (rounding 6e-8 on values near 1, twice), and M^2's rows sum to at most (1 + 2 * 3 * 3)^2
// = 361 in magnitude here: 5e-5 on values of order 1.
TEST(LargeSteps, StepIsTakenInTheSmoothParametrisation) {
  auto scene = test::sceneFromJson(kQuad);
  ParameterRegistry reg;
  ParameterOptions o;
  o.largeStepsLambda = 3.f;
  o.learningRate = 1.f;
  reg.add(*scene, "shapes/plane/vertices", o);
  ASSERT_EQ(reg.vertexEdges(reg.slots()[0]).size(), 5u) << "a quad: four sides and a diagonal";
  const std::vector<float> before = reg.read(*scene);
  std::vector<float> theta = before;
  const std::vector<double> g = pseudoRandom(theta.size(), 9);
  OptimizerState st;
  optimizerStep(OptimizerKind::Sgd, reg, g, theta, st);
  LargeSteps m(4, reg.vertexEdges(reg.slots()[0]), 3.0);
  std::vector<double> dx(theta.size());
  for (size_t i = 0; i < dx.size(); ++i) dx[i] = double(theta[i]) - double(before[i]);
  const std::vector<double> back = m.toU(m.toU(dx));
  for (size_t i = 0; i < g.size(); ++i) EXPECT_NEAR(back[i], -g[i], 5e-5) << i;
}

// adam_uniform: one second-moment scale per parameter, the largest over its values. At the first
// step m/c1 = g and v/c2 = g^2, so each value moves by lr g / max|g|.
TEST(LargeSteps, AdamUniformScalesByTheLargestSecondMoment) {
  auto scene = test::sceneFromJson(kQuad);
  ParameterRegistry reg;
  ParameterOptions o;
  o.learningRate = 0.1f;
  reg.add(*scene, "shapes/plane/vertices", o);
  const std::vector<float> before = reg.read(*scene);
  std::vector<float> theta = before;
  std::vector<double> g = pseudoRandom(theta.size(), 4);
  g[5] = 4.0;  // the largest
  OptimizerState st;
  optimizerStep(OptimizerKind::AdamUniform, reg, g, theta, st);
  for (size_t i = 0; i < g.size(); ++i) EXPECT_NEAR(double(before[i]) - double(theta[i]), 0.1 * g[i] / 4.0, 1e-6) << i;
}

}  // namespace
}  // namespace invr
