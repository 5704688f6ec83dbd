// The gradient engine against finite differences of the converged loss, for each parameter kind
// (albedo texel, scalar roughness, light intensity) and each light-sampling strategy.
//
// Reference: the forward renderer (independent code) at theta +- h with common random numbers
// and sampling distributions held fixed, converged loss L = mean (I - T)^2 estimated without bias. Its own noise is
// measured over independent seeds. Estimate: the mean of the engine's gradient over independent
// sessions (for restir each session burns in first, so reservoirs are reused). The check is
// |mean - fd| <= 4 sqrt(se_mean^2 + se_fd^2).
#include "core/diff/gradient_engine.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <map>

#include "core/diff/diff_scenes.h"
#include "core/diff/fd_reference.h"
#include "core/diff/gradient_stats.h"
#include <tbb/task_arena.h>
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/render/renderer.h"

namespace invr {
namespace {

// Albedo texels 0..47, roughness 48, point light 49..51, area light 52..54.
using Fixture = test::FdReference;

Fixture& fixture() {
  static Fixture f(test::kDiffScene, {"materials/wall/albedo", "materials/metal/roughness", "lights/bulb/intensity", "lights/lamp/intensity"});
  return f;
}

// One session of two steps (seed 9) on view 0: the second step's gradient.
std::vector<double> secondStepGradient(GradientEngine& engine) {
  EngineSession s;
  GradientRequest r;
  r.views = {0};
  r.seed = 9;
  engine.evaluate(r, s);
  r.step = 1;
  return engine.evaluate(r, s).gradient;
}

void checkMethod(GradientMethod method, bool forwardOnly = false, bool pixelNeighbours = true,
                 SamplerKind sampler = SamplerKind::Independent) {
  Fixture& f = fixture();
  GradientOptions o;
  o.method = method;
  o.sampler = sampler;
  o.forwardOnly = forwardOnly;
  o.pixelNeighbours = pixelNeighbours;
  o.sppPrimal = 4;
  o.sppGradient = 4;
  // One albedo texel of each checker colour, the roughness, one channel of each light.
  test::expectGradientMatchesFiniteDifferences(f, o, {0, 4, 48, 49, 50, 53}, gradientMethodName(method), [](size_t k) {
    return std::string(k < 48 ? "albedo" : k == 48 ? "roughness" : "intensity");
  });
}

TEST(GradientEngine, PtMatchesFiniteDifferences) { checkMethod(GradientMethod::Pt); }
TEST(GradientEngine, RisMatchesFiniteDifferences) { checkMethod(GradientMethod::Ris); }
TEST(GradientEngine, RestirMatchesFiniteDifferences) { checkMethod(GradientMethod::Restir); }
TEST(GradientEngine, RestirForwardOnlyMatchesFiniteDifferences) { checkMethod(GradientMethod::Restir, true); }
// Neighbours from the kd-tree only (what multi-view batches use), instead of last step's pixels.
TEST(GradientEngine, RestirKdTreeNeighboursMatchFiniteDifferences) { checkMethod(GradientMethod::Restir, false, false); }
// Stratified samples (each session's pixels get their own scramble): still unbiased.
TEST(GradientEngine, PtWithSobolSamplesMatchesFiniteDifferences) { checkMethod(GradientMethod::Pt, false, true, SamplerKind::Sobol); }
TEST(GradientEngine, RisWithSobolSamplesMatchesFiniteDifferences) { checkMethod(GradientMethod::Ris, false, true, SamplerKind::Sobol); }
// ReSTIR resamples a pixel's samples together, which needs them independent: its passes keep
// independent samples under the sobol sampler (InteriorEstimator::stratifiable), to the bit.
TEST(GradientEngine, RestirPassesKeepIndependentSamplesUnderSobol) {
  Fixture& f = fixture();
  std::vector<std::vector<double>> results;
  for (SamplerKind sampler : {SamplerKind::Independent, SamplerKind::Sobol}) {
    GradientOptions o;
    o.method = GradientMethod::Restir;
    o.sppGradient = 4;
    o.sampler = sampler;
    GradientEngine engine(*f.scene, f.reg, {f.target}, o);
    f.reg.write(f.theta, *f.scene);
    results.push_back(secondStepGradient(engine));
  }
  EXPECT_EQ(results[0], results[1]);
}

// ReSTIR reuses reservoirs created at earlier parameters: the support test and the combination
// must stay unbiased when theta changes every step, and where neighbours have different supports
// (the plate shadows the wall from both lights, so neighbours across a shadow edge see different
// lights). Each session renders five steps at perturbed parameters (every component moved by up
// to 15 %, the wall's albedo at `wallDuringWarmUp`), then one gradient step at theta; returns the
// mean over sessions and the finite differences there for the checked components.
struct ChangingThetaCheck {
  std::vector<size_t> components{0, 4, 6, 7, 49, 50};
  std::vector<double> z, relativeSe;
};
ChangingThetaCheck restirAfterChangingTheta(float wallDuringWarmUp) {
  Fixture& f = fixture();
  GradientOptions o;
  o.method = GradientMethod::Restir;
  o.sppPrimal = 4;
  o.sppGradient = 4;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  const int sessions = 256, warm = 5;
  std::vector<test::MeanSE> grad(f.reg.size());
  for (int i = 0; i < sessions; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 30000 + uint64_t(i);
    for (int b = 0; b < warm; ++b) {
      std::vector<float> moved = f.theta;
      for (size_t k = 0; k < moved.size(); ++k) moved[k] *= 1.f + 0.15f * std::sin(float(b * 7 + int(k)) + 0.5f * float(i));
      for (size_t c = 0; c < 48; ++c) moved[c] = wallDuringWarmUp;  // every wall texel
      f.reg.write(moved, *f.scene);
      GradientRequest rb = r;
      rb.renderOnly = b % 2 == 0;  // gradient steps too: both chains advance either way
      rb.step = uint64_t(b);
      engine.evaluate(rb, session);
    }
    f.reg.write(f.theta, *f.scene);
    r.step = uint64_t(warm);
    auto g = engine.evaluate(r, session).gradient;
    for (size_t k = 0; k < g.size(); ++k) grad[k].add(g[k]);
  }
  ChangingThetaCheck c;
  for (size_t k : c.components) {
    const test::MeanSE& fd = f.finiteDifference(k);
    double se = std::sqrt(grad[k].se() * grad[k].se() + fd.se() * fd.se());
    const double mean = grad[k].mean * test::mutation();
    std::printf("restir, wall at %g before, component %2zu: gradient %+.4e (se %.1e), finite difference %+.4e (se %.1e)\n",
                double(wallDuringWarmUp), k, mean, grad[k].se(), fd.mean, fd.se());
    c.z.push_back((mean - fd.mean) / se);
    c.relativeSe.push_back(se / std::abs(fd.mean));
  }
  return c;
}

// With the wall's albedo at its lower bound (the positive floor) in the steps before: unbiased, with
// 4 SE at most 5 % of each checked derivative.
TEST(GradientEngine, RestirStaysUnbiasedWhileThetaChangesEveryStep) {
  ChangingThetaCheck c = restirAfterChangingTheta(kPositiveFloor);
  for (size_t i = 0; i < c.components.size(); ++i) {
    EXPECT_LT(std::abs(c.z[i]), test::kSigmas) << "component " << c.components[i];
    test::expectPower("restir after changing theta, component " + std::to_string(c.components[i]), c.relativeSe[i], 1.0, 0.05);
  }
}

// The same check sees the bias a zero bound would cause (why the bounds stay off zero): with the
// wall at exactly 0 before, its reservoirs had an empty support that the current-parameter support
// test counts, and the derivatives come out 8-17 % low (the wall's and the lights'), far outside 4 SE.
TEST(GradientEngine, RestirCheckSeesTheBiasOfAZeroBound) {
  ChangingThetaCheck c = restirAfterChangingTheta(0.f);
  double worst = 0;
  for (double z : c.z) worst = std::max(worst, std::abs(z));
  EXPECT_GT(worst, 3 * test::kSigmas);
}

TEST(GradientEngine, DeterministicForAnyThreadCount) {
  // ReSTIR with independent samples; PT with 4 stratified samples per pixel.
  for (auto [method, sampler] : {std::pair{GradientMethod::Restir, SamplerKind::Independent}, std::pair{GradientMethod::Pt, SamplerKind::Sobol}}) {
    Fixture& f = fixture();
    GradientOptions o;
    o.method = method;
    o.sampler = sampler;
    o.sppGradient = sampler == SamplerKind::Sobol ? 4 : 1;
    GradientEngine engine(*f.scene, f.reg, {f.target}, o);
    f.reg.write(f.theta, *f.scene);
    std::vector<std::vector<double>> results;
    for (int threads : {1, 2, 3}) {
      tbb::task_arena arena(threads);
      arena.execute([&] { results.push_back(secondStepGradient(engine)); });
    }
    EXPECT_EQ(results[0], results[1]) << samplerKindName(sampler);
    EXPECT_EQ(results[0], results[2]) << samplerKindName(sampler);
  }
}

// --correlated-primal (Alg. 4's single sample): under PT the derivative pass traces the primal
// pass's paths, so its image is the primal render and the two-render loss mean((I1 - T)(I2 - T))
// is the primal's mean((I1 - T)^2); independent passes differ.
TEST(GradientEngine, CorrelatedPrimalTracesThePrimalsPaths) {
  Fixture& f = fixture();
  f.reg.write(f.theta, *f.scene);
  for (bool correlated : {false, true}) {
    GradientOptions o;
    o.method = GradientMethod::Pt;
    o.sppPrimal = o.sppGradient = 2;
    o.correlatedPrimal = correlated;
    GradientEngine engine(*f.scene, f.reg, {f.target}, o);
    EngineSession s;
    GradientRequest r;
    r.views = {0};
    r.seed = 5;
    const GradientResult g = engine.evaluate(r, s);
    if (correlated) EXPECT_NEAR(g.stats.loss(), g.stats.primal_loss(), 1e-6 * g.stats.primal_loss());
    else EXPECT_GT(std::abs(g.stats.loss() - g.stats.primal_loss()), 1e-3 * g.stats.primal_loss());
  }
}

TEST(GradientEngine, ReservoirsPersistAndCarryConfidence) {
  Fixture& f = fixture();
  for (bool pixelNeighbours : {true, false}) {
    GradientOptions o;
    o.method = GradientMethod::Restir;
    o.pixelNeighbours = pixelNeighbours;
    GradientEngine engine(*f.scene, f.reg, {f.target}, o);
    f.reg.write(f.theta, *f.scene);
    EngineSession s;
    GradientRequest r;
    r.views = {0};
    auto first = engine.evaluate(r, s);
    EXPECT_EQ(meanNeighbours(first.stats), 0.0);  // nothing to reuse yet
    r.step = 1;
    auto second = engine.evaluate(r, s);
    EXPECT_GT(meanNeighbours(second.stats), 0.9 * o.restir.neighbours) << pixelNeighbours;  // almost every point finds one
    EXPECT_GT(meanM(second.stats), double(o.restir.candidates) * 1.5) << pixelNeighbours;    // and carries its confidence
    EXPECT_GT(second.stats.reservoirs(), 0u);
    // One view, static scene: last step's pixels answer every search and no kd-tree is built.
    EXPECT_EQ(second.stats.kd_trees_built(), pixelNeighbours ? 0u : 2u);
  }
}

// Alg. 8 on a multi-view scene: after a step that renders view 4, the reservoirs view 0 left
// behind are kept exactly when camera 4 cannot see their point, checked here against camera rays
// (an independent visibility test), in their old order; a batch that holds their own view keeps
// none of them.
TEST(GradientEngine, MultiViewBatchesPreserveTheReservoirsNoViewCanSee) {
  Problem p = buildProblem(zooJob("backlit"));
  const Scene& scene = *p.scene;
  GradientOptions o = p.gradient;
  o.method = GradientMethod::Restir;
  o.sppPrimal = o.sppGradient = 1;
  o.maxDepth = 1;
  o.pixels.sampler = &pixelSampler("all");
  // Any image will do as a target: only the reservoirs are checked.
  GradientEngine engine(*p.scene, p.params, std::vector<Image>(scene.cameras.size(), Image(scene.width, scene.height, 3)), o);
  auto step = [&](EngineSession& s, uint64_t k, std::vector<int> views) {
    GradientRequest r;
    r.step = k;
    r.views = std::move(views);
    r.renderOnly = true;
    return engine.evaluate(r, s).stats;
  };
  EngineSession s;
  step(s, 0, {0});
  const std::vector<StoredReservoir> fromView0 = s.primal.items();
  ASSERT_GT(fromView0.size(), 1000u);
  invr::v1::GradientStats st = step(s, 1, {4});

  const Camera& cam = scene.cameras[4];
  auto seenBy4 = [&](const StoredReservoir& r) {
    Vec3 d = r.p - cam.eye;
    float dist = length(d), z = dot(d, cam.forward);
    if (!(z > 0.f)) return false;
    float aspect = float(scene.width) / float(scene.height);
    if (std::abs(dot(d, cam.right) / z) > cam.tanHalfFovY * aspect || std::abs(dot(d, cam.up) / z) > cam.tanHalfFovY) return false;
    SurfaceHit h;
    return !scene.intersect(cam.eye, d / dist, h) || h.t > dist * (1.f - 1e-3f);
  };
  size_t expected = 0, kept = 0;
  size_t next = 0;  // kept ones appear in their old order
  bool ordered = true;
  for (const auto& r : s.primal.items()) {
    if (r.view != 0) continue;
    ++kept;
    while (next < fromView0.size() && (fromView0[next].tri != r.tri || fromView0[next].b1 != r.b1 || fromView0[next].b2 != r.b2)) ++next;
    if (next == fromView0.size()) ordered = false;
    else ++next;
  }
  for (const auto& r : fromView0) expected += seenBy4(r) ? 0 : 1;
  EXPECT_TRUE(ordered);
  // Both chains preserve; the primal one is checked point by point.
  EXPECT_GT(st.reservoirs_preserved(), kept);
  EXPECT_GT(kept, fromView0.size() / 10);               // camera 4 sees part of what camera 0 saw,
  EXPECT_LT(kept, fromView0.size() - fromView0.size() / 10);  // and misses part of it
  // The two visibility tests may disagree at grazing points on the silhouette only.
  EXPECT_NEAR(double(kept), double(expected), 0.01 * double(fromView0.size())) << kept << " kept, " << expected << " expected";

  // A batch that holds view 0 again replaces every reservoir view 0 left (unmoved geometry).
  EngineSession again;
  step(again, 0, {0});
  EXPECT_EQ(step(again, 1, {4, 0}).reservoirs_preserved(), 0u);
}

// Alg. 8 with pixel mini-batches: a step that traces a quarter of the pixels replaces the
// reservoirs of the pixels it drew and carries every other one (their view is in the batch, but
// their pixel was not traced, so nothing replaced them). Checked against the batch's own draws:
// an old reservoir is kept exactly when the pixel it projects to was not drawn.
TEST(GradientEngine, PixelMiniBatchesCarryTheReservoirsOfUndrawnPixels) {
  Fixture& f = fixture();
  GradientOptions o;
  o.method = GradientMethod::Restir;
  o.pixels.sampler = &pixelSampler("uniform");
  const int P = f.scene->width * f.scene->height;
  o.pixels.samplesPerView = P / 4;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  f.reg.write(f.theta, *f.scene);
  EngineSession s;
  GradientRequest r;
  r.views = {0};
  r.seed = 77;
  r.renderOnly = true;
  engine.evaluate(r, s);
  const std::vector<StoredReservoir> old = s.primal.items();
  ASSERT_GT(old.size(), size_t(P / 8));
  r.step = 1;
  invr::v1::GradientStats st = engine.evaluate(r, s).stats;
  // The batch step 1 drew (the engine's own stream for it).
  PixelMap uniform;
  uniform.setProbabilities(std::vector<float>(size_t(P), 1.f / float(P)));
  PixelBatch drawn = drawPixelBatch(uniform, P / 4, RngKey{streamSeed(r.seed, kPixelBatchStream), 1, 0, 0, 0});
  size_t expected = 0;
  const Camera& cam = f.scene->cameras[0];
  for (const auto& q : old) {
    float px, py;
    ASSERT_TRUE(cam.project(q.p, f.scene->width, f.scene->height, px, py));
    expected += drawn.contains(size_t(py) * size_t(f.scene->width) + size_t(px)) ? 0 : 1;
  }
  size_t kept = 0;
  for (const auto& q : s.primal.items())
    for (const auto& o2 : old)
      if (o2.tri == q.tri && o2.b1 == q.b1 && o2.b2 == q.b2 && o2.mesh == q.mesh) {
        ++kept;
        break;
      }
  std::printf("old %zu, kept %zu, expected %zu (undrawn pixels), carried by both chains %zu\n", old.size(), kept, expected,
              st.reservoirs_carried());
  EXPECT_EQ(kept, expected);
  EXPECT_GT(double(kept), 0.6 * double(old.size()));  // about (1 - 1/P)^(P/4) = 78 % of the pixels go undrawn
  EXPECT_GE(st.reservoirs_carried(), kept);
}

TEST(GradientEngine, BadRequestsAreInputErrors) {
  Fixture& f = fixture();
  GradientEngine engine(*f.scene, f.reg, {f.target}, {});
  f.reg.write(f.theta, *f.scene);
  EngineSession s;
  GradientRequest r;
  EXPECT_THROW(engine.evaluate(r, s), InputError);  // no views
  r.views = {3};
  EXPECT_THROW(engine.evaluate(r, s), InputError);
  r.views = {0};
  GradientEngine noTarget(*f.scene, f.reg, {}, {});
  EXPECT_THROW(noTarget.evaluate(r, s), InputError);
}

}  // namespace
}  // namespace invr

namespace invr {
namespace {

// Non-finite samples are caught in one place, counted, and kept out of the loss and the gradient:
// an albedo texel poisoned with NaN leaves every gradient component finite (and the others'
// gradients intact), and the count says how many samples were dropped. For each light-sampling
// method, and for path replay.
TEST(GradientEngine, NonFiniteSamplesAreCountedAndDropped) {
  Fixture& f = fixture();
  std::vector<float> theta = f.theta;
  theta[0] = std::numeric_limits<float>::quiet_NaN();  // one albedo texel
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris, GradientMethod::Restir}) {
    for (int depth : {1, 3}) {
      if (depth > 1 && m != GradientMethod::Pt) continue;
      GradientOptions o;
      o.method = m;
      o.maxDepth = depth;
      GradientEngine engine(*f.scene, f.reg, {f.target}, o);
      f.reg.write(theta, *f.scene);
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 9;
      GradientResult g = engine.evaluate(r, session);
      EXPECT_GT(droppedSamples(g.stats), 0u) << gradientMethodName(m) << " depth " << depth;
      EXPECT_TRUE(std::isfinite(g.stats.loss())) << gradientMethodName(m) << " depth " << depth;
      size_t nonFinite = 0;
      for (double v : g.gradient) nonFinite += std::isfinite(v) ? 0 : 1;
      EXPECT_EQ(nonFinite, 0u) << gradientMethodName(m) << " depth " << depth;
      // The unaffected components still carry a gradient.
      EXPECT_NE(g.gradient[4], 0.0) << gradientMethodName(m) << " depth " << depth;
      EXPECT_NE(g.gradient[49], 0.0) << gradientMethodName(m) << " depth " << depth;
    }
  }
  f.reg.write(f.theta, *f.scene);  // leave the shared scene as the other tests expect it
}

}  // namespace
}  // namespace invr
