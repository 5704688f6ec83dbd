// Pixel sampling: the mini-batch gradient equals the full-image gradient in expectation, for every
// sampler, with direct illumination (PT and ReSTIR) and on a caustic seen by path tracing. Both
// sides are means over independent seeds; the check is |mean_batch - mean_all| <= 4 SE of the
// difference, with enough power to resolve a 25 % error.
#include "core/diff/pixel_sampler.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <set>

#include <google/protobuf/util/json_util.h>

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
std::vector<test::MeanSE> gradients(PixelSetup& s, GradientMethod method, const PixelSampler& sampler, int seeds, int samples,
                                    int stage1Stride = 2) {
  GradientOptions o;
  o.method = method;
  o.maxDepth = s.depth;
  o.pixels.sampler = &sampler;
  o.pixels.samplesPerView = samples;
  o.pixels.stage1Stride = stage1Stride;
  GradientEngine engine(*s.scene, s.reg, {s.target}, o);
  s.reg.write(s.theta, *s.scene);
  std::vector<test::MeanSE> g(s.reg.size() + 1);  // the last: the sum of all components
  for (int i = 0; i < seeds; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 5000 + uint64_t(i) + (sampler.miniBatch() ? 0 : 100000);
    if (method == GradientMethod::Restir) {  // reuse across steps with sparse pixel sets
      GradientRequest b = r;
      b.renderOnly = true;
      engine.evaluate(b, session);
      r.step = 1;
    }
    auto res = engine.evaluate(r, session);
    double sum = 0;
    for (size_t k = 0; k < res.gradient.size(); ++k) {
      g[k].add(res.gradient[k]);
      sum += res.gradient[k];
    }
    g.back().add(sum);
  }
  return g;
}

void checkUnbiased(PixelSetup& s, GradientMethod method, const PixelSampler& sampler, int seeds, int samples, std::initializer_list<size_t> components,
                   int allSeeds = 0) {
  // Full images have lower variance per evaluation: a quarter of the seeds unless told.
  auto all = gradients(s, method, pixelSampler("all"), allSeeds > 0 ? allSeeds : seeds / 4, 0);
  auto batch = gradients(s, method, sampler, seeds, samples);
  for (size_t k : components) {
    if (k == kSum) k = all.size() - 1;
    double se = std::sqrt(all[k].se() * all[k].se() + batch[k].se() * batch[k].se());
    const double mean = batch[k].mean * test::mutation();
    std::printf("%-9s %-6s component %2zu: batch %+.4e (se %.1e), all %+.4e (se %.1e)\n", sampler.name(),
                gradientMethodName(method), k, mean, batch[k].se(), all[k].mean, all[k].se());
    EXPECT_NEAR(mean, all[k].mean, test::kSigmas * se) << sampler.name() << " component " << k;
    test::expectPower(std::string(sampler.name()) + " " + gradientMethodName(method) + " component " + std::to_string(k), se, all[k].mean);
  }
}

PixelSetup& direct() {
  static PixelSetup s = makeSetup(test::kDiffScene, 1, {"materials/wall/albedo", "materials/metal/roughness", "lights/bulb/intensity"});
  return s;
}

// Two albedo texels (one of each checker colour), the point light's red intensity, and the sum.
// (The plate's roughness is left to the finite-difference tests: its gradient is too noisy here to
// resolve 10 % in seconds, and the pixel weights do not depend on the parameter kind.)
// Every registered mini-batch sampler (a new one is tested by registering it).
std::vector<std::string> miniBatchSamplers() {
  std::vector<std::string> names;
  for (const PixelSampler* k : pixelSamplers())
    if (k->miniBatch()) names.push_back(k->name());
  return names;
}
class EveryPixelSampler : public testing::TestWithParam<std::string> {};
TEST_P(EveryPixelSampler, IsUnbiased) { checkUnbiased(direct(), GradientMethod::Pt, pixelSampler(GetParam()), 4096, 96, {0, 4, 49, kSum}); }
INSTANTIATE_TEST_SUITE_P(PixelSampling, EveryPixelSampler, testing::ValuesIn(miniBatchSamplers()),
                         [](const testing::TestParamInfo<std::string>& info) { return info.param; });
// Each sampler reads its own message under optimization.pixel_samplers, by its name, over the
// job-wide pixel_* values; a message with no sampler of its name could not exist.
TEST(PixelSampling, EachSamplerReadsItsOwnOptions) {
  std::set<std::string> fields, names;
  const google::protobuf::Descriptor* d = invr::v1::PixelSamplerSpecs::descriptor();
  for (int i = 0; i < d->field_count(); ++i) fields.insert(d->field(i)->name());
  for (const PixelSampler* p : pixelSamplers()) names.insert(p->name());
  for (const std::string& f : fields) EXPECT_TRUE(names.count(f)) << "pixel_samplers." << f << " names no sampler";
  auto parse = [](const std::string& json) {
    invr::v1::OptimizationSpec o;
    EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(json, &o).ok()) << json;
    return parsePixelSamplingOptions(o, 64 * 64);
  };
  const PixelSamplingOptions shared = parse(R"({"pixel_sampler": "adaptive", "pixel_samples": 300, "pixel_defensive": 0.3, "pixel_refresh": 7})");
  EXPECT_EQ(shared.samplesPerView, 300);
  EXPECT_FLOAT_EQ(shared.defensive, 0.3f);
  EXPECT_EQ(shared.refreshEvery, 7);
  EXPECT_EQ(shared.levels, 4);
  EXPECT_EQ(shared.stage1Stride, 2);
  const PixelSamplingOptions own = parse(R"({"pixel_sampler": "adaptive", "pixel_samples": 300, "pixel_samplers": {"adaptive":
      {"samples": 500, "defensive": 0.5, "refresh": 3, "stage1_stride": 4, "levels": 2, "stage1_history": 8}}})");
  EXPECT_EQ(own.samplesPerView, 500);
  EXPECT_FLOAT_EQ(own.defensive, 0.5f);
  EXPECT_EQ(own.refreshEvery, 3);
  EXPECT_EQ(own.stage1Stride, 4);
  EXPECT_EQ(own.levels, 2);
  EXPECT_EQ(own.stage1History, 8);
  EXPECT_EQ(shared.stage1History, 1);
  EXPECT_THROW(parse(R"({"pixel_sampler": "adaptive", "pixel_samplers": {"adaptive": {"stage1_history": 2000}}})"), InputError);
  EXPECT_THROW(parse(R"({"pixel_sampler": "loss_grad", "pixel_samplers": {"loss_grad": {"stage1_history": -1}}})"), InputError);
  const PixelSamplingOptions lossGrad = parse(R"({"pixel_sampler": "loss_grad", "pixel_samplers": {"loss_grad": {"stage1_stride": 1}}})");
  EXPECT_EQ(lossGrad.stage1Stride, 1);
  EXPECT_EQ(parse(R"({"pixel_sampler": "uniform", "pixel_samplers": {"uniform": {"samples": 64}}})").samplesPerView, 64);
  EXPECT_THROW(parse(R"({"pixel_sampler": "loss_grad", "pixel_samplers": {"adaptive": {"levels": 2}}})"), InputError);
}

TEST(PixelSampling, AdaptiveWithRestirIsUnbiased) {
  checkUnbiased(direct(), GradientMethod::Restir, pixelSampler("adaptive"), 4096, 96, {0, 4, 49, kSum});
}
// Adaptive sampling's failure case (Yan et al. 2025): stage 1 traces one path per cell, and a
// caustic (a diffuse bounce that must find the glass sphere and refract to the lamp) is almost
// never among them, so the map puts next to nothing there and only the defensive mixture keeps
// the caustic's pixels drawable. The test checks, in order, that
//   1. stage 1 missed the caustic for real: the map gives the caustic's pixels under a third of
//      the probability their share of the gradient would call for;
//   2. the caustic matters: its pixels carry enough of the gradient sum that losing them would be
//      a deviation of more than 4 SE of this comparison (so the check below could see it);
//   3. the mini-batch gradient still matches the full-image one (the caustic texels and the sum).
TEST(PixelSampling, AdaptiveStaysUnbiasedOnACaustic) {
  static PixelSetup s = makeSetup(test::kCausticScene, 4, {"materials/floor/albedo"});
  const int W = s.scene->width, H = s.scene->height, P = W * H;
  // The caustic's pixels: floor pixels where paths of 4 vertices see much more than direct
  // illumination (the sphere itself, seen through, is not the caustic).
  s.reg.write(s.theta, *s.scene);
  RenderOptions ro;
  ro.spp = 1024;
  ro.seed = 17;
  ro.maxDepth = 1;
  Image direct = renderView(*s.scene, 0, ro).image;
  ro.maxDepth = 4;
  Image full = renderView(*s.scene, 0, ro).image;
  std::vector<float> caustic(size_t(P), 0.f);
  int causticPixels = 0;
  const Camera& cam = s.scene->cameras[0];
  auto onFloor = [&](int x, int y) {
    SurfaceHit h;
    return s.scene->intersect(cam.eye, cam.direction(float(x) + 0.5f, float(y) + 0.5f, W, H), h) &&
           s.scene->materials[size_t(s.scene->meshMaterial[h.mesh])].name == "floor";
  };
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (onFloor(x, y) && luminance(full.rgb(x, y)) > 2.f * luminance(direct.rgb(x, y)) + 0.05f) {
        caustic[size_t(y * W + x)] = 1.f;
        ++causticPixels;
      }
  std::printf("caustic: %d of %d pixels\n", causticPixels, P);
  ASSERT_GT(causticPixels, 4);
  ASSERT_LT(causticPixels, P / 8);

  // 1. Stage 1 misses the caustic: one path from a cell on the spot finds it easily (the sphere
  // fills much of the sky of the floor under it), so the grid is chosen to miss it, as any grid
  // coarser than a caustic can: the smallest stride with no cell centre on the spot.
  auto nearCaustic = [&](int x, int y) {
    for (int dy = 0; dy <= 0; ++dy)
      for (int dx = 0; dx <= 0; ++dx) {
        int xx = x + dx, yy = y + dy;
        if (xx >= 0 && yy >= 0 && xx < W && yy < H && caustic[size_t(yy * W + xx)] > 0.f) return true;
      }
    return false;
  };
  int stride = 0;
  for (int st = 2; st <= 8 && stride == 0; ++st) {
    bool clear = true;
    for (int y = st / 2; y < H && clear; y += st)
      for (int x = st / 2; x < W && clear; x += st) clear = !nearCaustic(x, y);
    if (clear) stride = st;
  }
  ASSERT_GT(stride, 0) << "no stage-1 grid misses the caustic";
  std::printf("stage-1 stride %d misses the caustic\n", stride);
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = s.depth;
  o.pixels.sampler = &pixelSampler("adaptive");
  o.pixels.samplesPerView = 96;
  o.pixels.stage1Stride = stride;
  GradientEngine engine(*s.scene, s.reg, {s.target}, o);
  double causticMass = 0;
  const int maps = 32;
  for (int i = 0; i < maps; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 800 + uint64_t(i);
    engine.evaluate(r, session);
    const auto& p = session.pixelMaps.at(0).p;
    for (int k = 0; k < P; ++k) causticMass += caustic[size_t(k)] * double(p[size_t(k)]) / maps;
  }
  std::printf("probability mass on the caustic %.3f (defensive share alone %.3f)\n", causticMass,
              double(o.pixels.defensive) * causticPixels / P);

  // 3. Unbiased, for the texels under the caustic and the sum.
  auto all = gradients(s, GradientMethod::Pt, pixelSampler("all"), 4096, 0);
  auto batch = gradients(s, GradientMethod::Pt, pixelSampler("adaptive"), 8192, 96, stride);
  const size_t sum = all.size() - 1;
  for (size_t k : {size_t(0), size_t(12), sum}) {
    double se = std::sqrt(all[k].se() * all[k].se() + batch[k].se() * batch[k].se());
    const double mean = batch[k].mean * test::mutation();
    std::printf("adaptive on the caustic, component %2zu: batch %+.4e (se %.1e), all %+.4e (se %.1e)\n", k, mean, batch[k].se(),
                all[k].mean, all[k].se());
    EXPECT_NEAR(mean, all[k].mean, test::kSigmas * se) << "component " << k;
    // The texels under the caustic claim 10 %; the sum 20 %, which is what this test needs of it:
    // to see the caustic's pixels (28 % of the sum, below) go missing.
    test::expectPower("adaptive on the caustic, component " + std::to_string(k), se, all[k].mean, k == sum ? 0.20 : 0.10);
  }

  // 2. The caustic's share of the gradient sum, from batches drawn on its pixels only (weights
  // 1 / (N p) make them an unbiased estimate of the caustic pixels' part).
  GradientOptions only = o;
  only.pixels.refreshEvery = 1 << 30;  // keep the preset map
  GradientEngine onCaustic(*s.scene, s.reg, {s.target}, only);
  test::MeanSE part;
  for (int i = 0; i < 1024; ++i) {
    EngineSession session;
    session.pixelMaps[0].setProbabilities(defensiveMixture(caustic, 0.f));
    GradientRequest r;
    r.views = {0};
    r.seed = 90000 + uint64_t(i);
    double total = 0;
    for (double g : onCaustic.evaluate(r, session).gradient) total += g;
    part.add(total);
  }
  const double seDiff = std::sqrt(all[sum].se() * all[sum].se() + batch[sum].se() * batch[sum].se());
  std::printf("caustic pixels' part of the gradient sum %+.4e (se %.1e) of %+.4e; 4 SE of the comparison %.1e\n", part.mean, part.se(),
              all[sum].mean, test::kSigmas * seDiff);
  EXPECT_GT(std::abs(part.mean) - test::kSigmas * part.se(), test::kSigmas * seDiff)
      << "the caustic carries too little of the gradient for the comparison to notice it missing";
  // Back to 1: the map gives the caustic under a third of the probability its share of the
  // gradient would call for (with stage 1's default grid, which has cells on the spot, it gives
  // about half: 15 % of the mass for 28 % of the gradient).
  const double share = std::abs(part.mean) / std::abs(all[sum].mean);
  std::printf("caustic: %.1f %% of the gradient sum, %.1f %% of the probability mass\n", 100 * share, 100 * causticMass);
  EXPECT_LT(causticMass, share / 3) << "stage 1 found the caustic: the test no longer exercises the defensive mixture";
}

// The maps' history (stage1_history = K): the plain mean of the first K passes, then an
// exponential mean giving the newest pass 1/K; a pass on another grid starts it again.
TEST(PixelSampling, Stage1HistoryAveragesThePassesItHolds) {
  auto pass = [](float v, int gw) {
    Stage1 s;
    s.gw = gw, s.gh = 1, s.stride = 2, s.width = 2 * gw, s.height = 2, s.passes = 1;
    s.adjointAbs.assign(size_t(3 * gw), v);
    s.adjointSq.assign(size_t(3 * gw), v * v);
    s.derivSq.assign(size_t(gw), 2 * v);
    s.guide.assign(size_t(6 * 4 * gw), v);
    return s;
  };
  Stage1 h;
  for (float v : {1.f, 2.f, 3.f}) accumulateStage1(h, pass(v, 4), 4);
  EXPECT_EQ(h.passes, 3);
  EXPECT_FLOAT_EQ(h.adjointAbs[0], 2.f);               // (1 + 2 + 3) / 3
  EXPECT_FLOAT_EQ(h.adjointSq[5], 14.f / 3.f);         // (1 + 4 + 9) / 3: the mean square, not the mean's square
  EXPECT_FLOAT_EQ(h.derivSq[3], 4.f);
  EXPECT_FLOAT_EQ(h.guide[0], 3.f);                    // the newest pass's guide
  accumulateStage1(h, pass(6, 4), 4);                  // the fourth: (1 + 2 + 3 + 6) / 4
  EXPECT_FLOAT_EQ(h.adjointAbs[1], 3.f);
  accumulateStage1(h, pass(7, 4), 4);                  // then 3 + (7 - 3) / 4
  EXPECT_EQ(h.passes, 4);
  EXPECT_FLOAT_EQ(h.adjointAbs[2], 4.f);
  accumulateStage1(h, pass(5, 8), 4);                  // another grid: only the fresh pass
  EXPECT_EQ(h.passes, 1);
  EXPECT_EQ(h.derivSq.size(), 8u);
  EXPECT_FLOAT_EQ(h.adjointAbs[0], 5.f);
  accumulateStage1(h, pass(9, 8), 1);                  // window 1: each pass alone
  EXPECT_FLOAT_EQ(h.adjointAbs[0], 9.f);
}

// The engine keeps the history in the session: with stage1_history 2 and a refresh every step,
// step 1's map is the one built from the mean of steps 0's and 1's stage-1 passes (the same
// passes measureStage1 gives for those requests), and not the one from step 1's pass alone.
TEST(PixelSampling, TheSessionsMapsComeFromTheStage1History) {
  PixelSetup& s = direct();
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.pixels.sampler = &pixelSampler("adaptive");
  o.pixels.samplesPerView = 64;
  o.pixels.refreshEvery = 1;
  o.pixels.stage1History = 2;
  GradientEngine engine(*s.scene, s.reg, {s.target}, o);
  s.reg.write(s.theta, *s.scene);
  EngineSession session;
  std::vector<GradientRequest> requests(2);
  for (uint64_t step = 0; step < 2; ++step) {
    requests[step].views = {0};
    requests[step].seed = 77;
    requests[step].step = step;
    engine.evaluate(requests[step], session);
  }
  ASSERT_EQ(session.stage1History.at(0).passes, 2);
  Stage1 h;
  for (const GradientRequest& r : requests) accumulateStage1(h, engine.measureStage1(0, r), 2);
  const std::vector<float> expected = buildPixelMap(o.pixels, h, 1).p;
  const std::vector<float> alone = buildPixelMap(o.pixels, engine.measureStage1(0, requests[1]), 1).p;
  const std::vector<float>& got = session.pixelMaps.at(0).p;
  ASSERT_EQ(got.size(), expected.size());
  double offHistory = 0, offAlone = 0;
  for (size_t j = 0; j < got.size(); ++j) {
    offHistory = std::max(offHistory, double(std::abs(got[j] - expected[j])));
    offAlone = std::max(offAlone, double(std::abs(got[j] - alone[j])));
  }
  EXPECT_EQ(offHistory, 0.0);
  EXPECT_GT(offAlone, 0.0) << "one pass and two give the same map: the test cannot tell them apart";
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
  EXPECT_THROW(pixelSampler("random"), InputError);
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
    o.pixels.sampler = &pixelSampler("adaptive");
    o.pixels.samplesPerView = draws;
    o.pixels.refreshEvery = 1 << 30;  // keep the preset map
    GradientEngine engine(*s.scene, s.reg, {s.target}, o);
    s.reg.write(s.theta, *s.scene);
    std::vector<double> values;
    for (int i = 0; i < 256; ++i) {
      EngineSession session;
      session.pixelMaps[0].setProbabilities(defensiveMixture(q, 1e-4f));
      GradientRequest r;
      r.views = {0};
      r.seed = 900 + uint64_t(i);
      auto res = engine.evaluate(r, session);
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
