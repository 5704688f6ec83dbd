// The render-time model of time-aware variance losses (Yan et al. 2024, Eq. 36) against
// independent references: its derivative against central differences of the model itself, and
// the model's linearity in each survival probability against ray counts measured at two
// survival settings (the counts are random: 4 SE tolerances, 4 SE under 10 % of the value).
#include "core/diff/render_cost.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "core/render/renderer.h"
#include "test_util.h"

namespace invr {
namespace {

TEST(RenderCost, DerivativeMatchesTheModel) {
  // Expected counts of a walk with per-depth costs c_d at survival q: R_d = N c_d prod_{k<d} q_k
  // (the last survival value repeats), so t(q) = sum_d c_d prod_{k<d} q_k.
  const std::vector<double> c = {2.0, 3.0, 2.5, 2.0, 1.5, 1.0};
  const double N = 1e6;
  auto model = [&](const std::vector<float>& q) {
    double t = 0, prod = 1;
    for (size_t d = 0; d < c.size(); ++d) {
      t += c[d] * prod;
      prod *= q[std::min(d, q.size() - 1)];
    }
    return t;
  };
  const std::vector<float> q = {0.9f, 0.6f, 0.75f, 0.5f};  // q_3 repeats for bounces 4 and 5
  RayStats rays;
  rays.camera = uint64_t(N);
  double prod = 1;
  for (size_t d = 0; d < c.size(); ++d) {
    rays.byDepth[d] = uint64_t(std::llround(N * c[d] * prod));
    prod *= q[std::min(d, q.size() - 1)];
  }
  RenderCost cost = renderCostByDepth(rays, q);
  EXPECT_NEAR(cost.raysPerSample, model(q), 1e-5);
  ASSERT_EQ(cost.dSurvival.size(), q.size());
  for (size_t i = 0; i < q.size(); ++i) {
    const float h = 1e-3f;
    auto plus = q, minus = q;
    plus[i] += h;
    minus[i] -= h;
    const double fd = (model(plus) - model(minus)) / (double(plus[i]) - double(minus[i]));
    EXPECT_NEAR(cost.dSurvival[i], fd, 1e-4 * std::abs(fd)) << "survival " << i;
  }
  // Throughput roulette: the measured cost, nothing to differentiate.
  RenderCost throughput = renderCostByDepth(rays, {});
  EXPECT_NEAR(throughput.raysPerSample, cost.raysPerSample, 1e-12);
  EXPECT_TRUE(throughput.dSurvival.empty());
}

// Inside a diffuse box lit by a point light: paths run to depth 5 unless roulette ends them.
constexpr const char* kBox = R"({
  "materials": [{"name": "walls", "diffuse": {"albedo": {"value": 0.7}}}],
  "shapes": [{"name": "box", "material": "walls", "box": {}, "transform": {"scale": {"x": 2, "y": 2, "z": 2}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0.5, "y": 1.2, "z": -0.5}, "intensity": {"r": 2, "g": 2, "b": 2}}}],
  "views": [{"eye": {"z": 1.5}, "target": {"z": -1}, "fov_y_degrees": 60}],
  "film": {"width": 8, "height": 8}
})";

TEST(RenderCost, MeasuredCostIsLinearInEachSurvival) {
  // t is linear in q_2 with slope dt/dq_2: the cost measured at q_2 + 0.3 minus the cost at q_2,
  // over 0.3, must match the derivative calibrated at q_2.
  auto scene = test::sceneFromJson(kBox);
  const std::vector<float> q = {0.9f, 0.7f, 0.5f, 0.8f, 0.6f};
  RenderOptions ro;
  ro.maxDepth = 5;
  ro.spp = 256;
  auto measure = [&](const std::vector<float>& survival, uint64_t seed) {
    scene->sampling.survival = survival;
    ro.seed = seed;
    return renderCostByDepth(renderView(*scene, 0, ro).rays, survival);
  };
  auto raised = q;
  raised[2] += 0.3f;
  test::MeanSE slope, predicted;
  for (uint64_t b = 0; b < 24; ++b) {
    RenderCost at = measure(q, 100 + b), up = measure(raised, 500 + b);
    slope.add((up.raysPerSample - at.raysPerSample) / 0.3);
    predicted.add(at.dSurvival[2]);
  }
  const double se = std::hypot(slope.se(), predicted.se());
  std::printf("dt/dq_3: measured %.5f (se %.1e), calibrated %.5f (se %.1e)\n", slope.mean, slope.se(), predicted.mean, predicted.se());
  EXPECT_NEAR(predicted.mean * test::mutation(), slope.mean, test::kSigmas * se);
  test::expectPower("dt/dq_2 against the measured slope", se, slope.mean);
  // The first survival changes every bounce after the first: its slope is the largest.
  RenderCost at = measure(q, 7);
  EXPECT_GT(at.dSurvival[0], at.dSurvival[2]);
}

}  // namespace
}  // namespace invr
