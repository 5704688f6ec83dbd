// Pixel sampling: the mini-batch gradient equals the full-image gradient in expectation, for every
// sampler, with direct illumination (PT and ReSTIR) and on a caustic seen by path tracing. Both
// sides are means over independent seeds; the check is |mean_batch - mean_all| <= 4 SE of the
// difference, with enough power to resolve a 25 % error.
#include "core/diff/pixel_sampler.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "core/diff/diff_scenes.h"
#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/render/renderer.h"

namespace invr {
namespace {

struct PixelSetup {
  std::unique_ptr<Scene> scene;
  ParameterRegistry reg;
  std::vector<float> theta;
  Image target;
  int depth = 1;
};

PixelSetup makeSetup(const char* json, int depth, std::initializer_list<const char*> params) {
  PixelSetup s;
  s.scene = test::sceneFromJson(json);
  s.depth = depth;
  for (const char* p : params) s.reg.add(*s.scene, p);
  std::vector<float> truth = s.reg.read(*s.scene);
  s.reg.write(truth, *s.scene);
  RenderOptions o;
  o.spp = 256;
  o.seed = 3;
  o.maxDepth = depth;
  s.target = renderView(*s.scene, 0, o).image;
  s.theta = truth;
  for (auto& v : s.theta) v *= 0.7f;
  return s;
}

// Mean and SE of each gradient component, and of their sum (a linear functional of the gradient,
// with a better signal-to-noise ratio), over `seeds` independent evaluations (a fresh session
// each, so stage 1 runs every time: the maps are random too).
constexpr size_t kSum = SIZE_MAX;
std::vector<test::MeanSE> gradients(PixelSetup& s, GradientMethod method, PixelSampler sampler, int seeds, int samples) {
  GradientOptions o;
  o.method = method;
  o.maxDepth = s.depth;
  o.pixels.sampler = sampler;
  o.pixels.samplesPerView = samples;
  GradientEngine engine(*s.scene, s.reg, {s.target}, o);
  std::vector<test::MeanSE> g(s.reg.size() + 1);  // the last: the sum of all components
  for (int i = 0; i < seeds; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 5000 + uint64_t(i) + (sampler == PixelSampler::All ? 100000 : 0);
    if (method == GradientMethod::Restir) {  // reuse across steps with sparse pixel sets
      GradientRequest b = r;
      b.renderOnly = true;
      engine.evaluate(s.theta, b, session);
      r.step = 1;
    }
    auto res = engine.evaluate(s.theta, r, session);
    double sum = 0;
    for (size_t k = 0; k < res.gradient.size(); ++k) {
      g[k].add(res.gradient[k]);
      sum += res.gradient[k];
    }
    g.back().add(sum);
  }
  return g;
}

void checkUnbiased(PixelSetup& s, GradientMethod method, PixelSampler sampler, int seeds, int samples, std::initializer_list<size_t> components,
                   int allSeeds = 0) {
  // Full images have lower variance per evaluation: a quarter of the seeds unless told.
  auto all = gradients(s, method, PixelSampler::All, allSeeds > 0 ? allSeeds : seeds / 4, 0);
  auto batch = gradients(s, method, sampler, seeds, samples);
  for (size_t k : components) {
    if (k == kSum) k = all.size() - 1;
    double se = std::sqrt(all[k].se() * all[k].se() + batch[k].se() * batch[k].se());
    std::printf("%-9s %-6s component %2zu: batch %+.4e (se %.1e), all %+.4e (se %.1e)\n", pixelSamplerName(sampler),
                gradientMethodName(method), k, batch[k].mean, batch[k].se(), all[k].mean, all[k].se());
    EXPECT_NEAR(batch[k].mean, all[k].mean, test::kSigmas * se) << pixelSamplerName(sampler) << " component " << k;
    EXPECT_LT(test::kSigmas * se, 0.25 * std::abs(all[k].mean)) << pixelSamplerName(sampler) << " component " << k << ": no power";
  }
}

PixelSetup& direct() {
  static PixelSetup s = makeSetup(test::kDiffScene, 1, {"materials/wall/albedo", "materials/metal/roughness", "lights/bulb/intensity"});
  return s;
}

// Two albedo texels (one of each checker colour), the point light's red intensity, and the sum.
// (The plate's roughness is left to the finite-difference tests: its gradient is too noisy here to
// resolve 25 % in a second, and the pixel weights do not depend on the parameter kind.)
TEST(PixelSampling, UniformIsUnbiased) { checkUnbiased(direct(), GradientMethod::Pt, PixelSampler::Uniform, 512, 96, {0, 4, 49, kSum}); }
TEST(PixelSampling, LossGradIsUnbiased) { checkUnbiased(direct(), GradientMethod::Pt, PixelSampler::LossGrad, 512, 96, {0, 4, 49, kSum}); }
TEST(PixelSampling, AdaptiveIsUnbiased) { checkUnbiased(direct(), GradientMethod::Pt, PixelSampler::Adaptive, 512, 96, {0, 4, 49, kSum}); }
TEST(PixelSampling, AdaptiveWithRestirIsUnbiased) {
  checkUnbiased(direct(), GradientMethod::Restir, PixelSampler::Adaptive, 512, 96, {0, 4, 49, kSum});
}
TEST(PixelSampling, AdaptiveStaysUnbiasedOnACaustic) {
  static PixelSetup s = makeSetup(test::kCausticScene, 4, {"materials/floor/albedo"});
  // The sum is dominated by the texels under the caustic (heavy-tailed: many seeds on both sides).
  checkUnbiased(s, GradientMethod::Pt, PixelSampler::Adaptive, 4096, 96, {0, 12, kSum}, 4096);
}

TEST(PixelSampling, EveryPixelKeepsAProbabilityAndWeightsMatchTheDraws) {
  std::vector<float> map(100, 0.f);
  map[7] = 5.f;  // a map that would ignore all but one pixel
  PixelMap pm;
  pm.setProbabilities(defensiveMixture(map, 0.2f));
  const auto& p = pm.p;
  double sum = 0;
  for (float v : p) {
    EXPECT_GT(v, 0.f);
    sum += v;
  }
  EXPECT_NEAR(sum, 1.0, 1e-5);
  EXPECT_NEAR(p[7], 0.8 + 0.002, 1e-5);
  // E[weight_j] = 1 for every j: mean over many draws.
  std::vector<double> mean(100, 0.0);
  const int reps = 4000;
  for (int r = 0; r < reps; ++r) {
    PixelBatch b = drawPixelBatch(pm, 10, RngKey{1, uint64_t(r), 0, 0, 0});
    uint32_t draws = 0;
    for (size_t j = 0; j < 100; ++j) {
      mean[j] += b.weight[j] / reps;
      draws += b.draws[j];
      EXPECT_EQ(b.draws[j] > 0, b.weight[j] > 0.f);
    }
    EXPECT_EQ(draws, 10u);
  }
  EXPECT_NEAR(mean[7], 1.0, 0.05);
  EXPECT_NEAR(mean[50], 1.0, 0.25);  // rare pixel: large weights, more noise
  EXPECT_THROW(pixelSamplerFromName("random"), InputError);
}

// A pixel drawn c times is traced c times, each draw on streams of its own (Alg. 1), not once
// with weight c: with a map that puts nearly all mass on one pixel, its value over independent
// seeds must have about 1/8 the variance with N = 8 draws as with N = 1. (Tracing it once would
// give a ratio of 1.) Both variances from 256 seeds: the ratio's relative error is about 0.13 for
// normal values; the bounds are a factor of 2 either side.
TEST(PixelSampling, EveryDrawGetsPathsOfItsOwn) {
  PixelSetup& s = direct();
  const int W = s.scene->width, H = s.scene->height;
  const size_t pixel = size_t(H / 2) * size_t(W) + size_t(W / 2);
  std::vector<float> q(size_t(W) * size_t(H), 0.f);
  q[pixel] = 1.f;
  auto pixelVariance = [&](int draws) {
    GradientOptions o;
    o.method = GradientMethod::Pt;
    o.pixels.sampler = PixelSampler::Adaptive;
    o.pixels.samplesPerView = draws;
    o.pixels.refreshEvery = 1 << 30;  // keep the preset map
    GradientEngine engine(*s.scene, s.reg, {s.target}, o);
    std::vector<double> values;
    for (int i = 0; i < 256; ++i) {
      EngineSession session;
      session.pixelMaps[0].setProbabilities(defensiveMixture(q, 1e-4f));
      GradientRequest r;
      r.views = {0};
      r.seed = 900 + uint64_t(i);
      auto res = engine.evaluate(s.theta, r, session);
      const Image& im = res.renders[0];
      values.push_back(double(im.data()[3 * pixel] + im.data()[3 * pixel + 1] + im.data()[3 * pixel + 2]));
    }
    double mean = 0, var = 0;
    for (double x : values) mean += x / double(values.size());
    for (double x : values) var += (x - mean) * (x - mean) / double(values.size() - 1);
    return var;
  };
  const double one = pixelVariance(1), eight = pixelVariance(8);
  std::printf("pixel value variance: 1 draw %.4e, 8 draws %.4e, ratio %.2f (expected 8)\n", one, eight, one / eight);
  ASSERT_GT(one, 0.0);
  EXPECT_GT(one / eight, 4.0);
  EXPECT_LT(one / eight, 16.0);
}

}  // namespace
}  // namespace invr
