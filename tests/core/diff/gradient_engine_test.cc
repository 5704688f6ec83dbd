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
#include <tbb/task_arena.h>
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

void checkMethod(GradientMethod method, bool forwardOnly = false, bool pixelNeighbours = true) {
  Fixture& f = fixture();
  GradientOptions o;
  o.method = method;
  o.forwardOnly = forwardOnly;
  o.pixelNeighbours = pixelNeighbours;
  o.sppPrimal = 4;
  o.sppGradient = 4;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  const int sessions = 48, burnIn = method == GradientMethod::Restir ? 3 : 0;
  std::vector<test::MeanSE> grad(f.reg.size());
  for (int i = 0; i < sessions; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 1000 + uint64_t(i);
    for (int b = 0; b < burnIn; ++b) {
      GradientRequest rb = r;
      rb.renderOnly = true;
      rb.step = uint64_t(b);
      engine.evaluate(f.theta, rb, session);
    }
    r.step = uint64_t(burnIn);
    auto g = engine.evaluate(f.theta, r, session).gradient;
    for (size_t k = 0; k < g.size(); ++k) grad[k].add(g[k]);
  }
  // One albedo texel of each checker colour, the roughness, one channel of each light.
  for (size_t k : {size_t(0), size_t(4), size_t(48), size_t(49), size_t(50), size_t(53)}) {
    const test::MeanSE& fd = f.finiteDifference(k);
    double se = std::sqrt(grad[k].se() * grad[k].se() + fd.se() * fd.se());
    std::printf("%-6s component %2zu: gradient %+.4e (se %.1e), finite difference %+.4e (se %.1e)\n",
                gradientMethodName(method), k, grad[k].mean, grad[k].se(), fd.mean, fd.se());
    EXPECT_NEAR(grad[k].mean, fd.mean, test::kSigmas * se)
        << gradientMethodName(method) << " component " << k << " (" << (k < 48 ? "albedo" : k == 48 ? "roughness" : "intensity")
        << ")";
    // The comparison must have power: the combined SE resolves a 30 % error.
    EXPECT_LT(test::kSigmas * se, 0.3 * std::abs(fd.mean)) << gradientMethodName(method) << " component " << k;
  }
}

TEST(GradientEngine, PtMatchesFiniteDifferences) { checkMethod(GradientMethod::Pt); }
TEST(GradientEngine, RisMatchesFiniteDifferences) { checkMethod(GradientMethod::Ris); }
TEST(GradientEngine, RestirMatchesFiniteDifferences) { checkMethod(GradientMethod::Restir); }
TEST(GradientEngine, RestirForwardOnlyMatchesFiniteDifferences) { checkMethod(GradientMethod::Restir, true); }
// Neighbours from the kd-tree only (what multi-view batches use), instead of last step's pixels.
TEST(GradientEngine, RestirKdTreeNeighboursMatchFiniteDifferences) { checkMethod(GradientMethod::Restir, false, false); }

TEST(GradientEngine, DeterministicForAnyThreadCount) {
  Fixture& f = fixture();
  GradientOptions o;
  o.method = GradientMethod::Restir;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  std::vector<std::vector<double>> results;
  for (int threads : {1, 2, 3}) {
    tbb::task_arena arena(threads);
    arena.execute([&] {
      EngineSession s;
      GradientRequest r;
      r.views = {0};
      r.seed = 9;
      engine.evaluate(f.theta, r, s);
      r.step = 1;
      results.push_back(engine.evaluate(f.theta, r, s).gradient);
    });
  }
  EXPECT_EQ(results[0], results[1]);
  EXPECT_EQ(results[0], results[2]);
}

TEST(GradientEngine, ReservoirsPersistAndCarryConfidence) {
  Fixture& f = fixture();
  for (bool pixelNeighbours : {true, false}) {
    GradientOptions o;
    o.method = GradientMethod::Restir;
    o.pixelNeighbours = pixelNeighbours;
    GradientEngine engine(*f.scene, f.reg, {f.target}, o);
    EngineSession s;
    GradientRequest r;
    r.views = {0};
    auto first = engine.evaluate(f.theta, r, s);
    EXPECT_EQ(first.stats.meanNeighbours, 0.0);  // nothing to reuse yet
    r.step = 1;
    auto second = engine.evaluate(f.theta, r, s);
    EXPECT_GT(second.stats.meanNeighbours, 0.9 * o.restir.neighbours) << pixelNeighbours;  // almost every point finds one
    EXPECT_GT(second.stats.meanM, double(o.restir.candidates) * 1.5) << pixelNeighbours;    // and carries its confidence
    EXPECT_GT(second.stats.reservoirs, 0u);
    // One view, static scene: last step's pixels answer every search and no kd-tree is built.
    EXPECT_EQ(second.stats.kdTreesBuilt, pixelNeighbours ? 0 : 2);
  }
}

TEST(GradientEngine, BadRequestsAreInputErrors) {
  Fixture& f = fixture();
  GradientEngine engine(*f.scene, f.reg, {f.target}, {});
  EngineSession s;
  GradientRequest r;
  EXPECT_THROW(engine.evaluate(f.theta, r, s), InputError);  // no views
  r.views = {3};
  EXPECT_THROW(engine.evaluate(f.theta, r, s), InputError);
  r.views = {0};
  EXPECT_THROW(engine.evaluate(std::vector<float>(3), r, s), InputError);  // wrong theta size
  GradientEngine noTarget(*f.scene, f.reg, {}, {});
  EXPECT_THROW(noTarget.evaluate(f.theta, r, s), InputError);
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
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 9;
      GradientResult g = engine.evaluate(theta, r, session);
      EXPECT_GT(g.stats.nonFiniteSamples, 0u) << gradientMethodName(m) << " depth " << depth;
      EXPECT_TRUE(std::isfinite(g.stats.loss)) << gradientMethodName(m) << " depth " << depth;
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
