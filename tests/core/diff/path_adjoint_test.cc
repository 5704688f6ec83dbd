// The adjoint visitor (multi-bounce derivatives, replaying each path's recorded vertices) against
// finite differences of the converged loss, on a scene where the wall's albedo and the sphere's
// roughness are seen only through a glossy mirror. Reference: the forward renderer (NEE + MIS,
// same depth) at theta +- h with common random numbers: it shares the walk, so this checks the
// derivatives against the primal they differentiate (the walk itself is checked against an
// independent tracer in tests/core/render/path_walk_test.cc). The check is
// |mean - fd| <= 4 sqrt(se_mean^2 + se_fd^2), as for the direct-illumination estimators.
#include "core/diff/path_adjoint.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "core/diff/diff_scenes.h"
#include "core/diff/fd_reference.h"
#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/render/renderer.h"

namespace invr {
namespace {

constexpr int kDepth = 3;
constexpr int kSessions = 512;

// Wall albedo 0..47 and the sphere's roughness 49 are seen only in the mirror (roughness 48);
// the lamp's intensity is 50..52. The forward renderer runs NEE + MIS paths of the same depth.
struct ReplayFixture : test::FdReference {
  ReplayFixture()
      : FdReference(test::kReflectionScene,
                    {"materials/wall/albedo", "materials/mirror/roughness", "materials/gloss/roughness", "lights/lamp/intensity"},
                    [] {
                      RenderOptions o;
                      o.maxDepth = kDepth;
                      o.estimator = LightEstimator::NeeMis;
                      return o;
                    }(),
                    256) {
    fdSeeds = 8;
  }
};

TEST(PathAdjoint, GradientsMatchFiniteDifferencesThroughAReflection) {
  ReplayFixture f;
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = kDepth;
  o.sppPrimal = 4;
  o.sppGradient = 16;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  f.reg.write(f.theta, *f.scene);
  std::vector<test::MeanSE> grad(f.reg.size());
  for (int i = 0; i < kSessions; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 2000 + uint64_t(i);
    auto g = engine.evaluate(r, session).gradient;
    for (size_t k = 0; k < g.size(); ++k) grad[k].add(g[k]);
  }
  // The comparison must have power: 4 combined SE are at most 10 % of the derivative; 15 % for
  // the mirror's roughness and 60 % for the sphere's, whose effect reaches the image only through
  // the mirror's glossy lobe (enough to catch a sign error or a factor of two; 10 % would take
  // minutes).
  for (size_t k : {size_t(0), size_t(4), size_t(48), size_t(49), size_t(50)}) {
    const double claim = k == 49 ? 0.6 : k == 48 ? 0.15 : 0.1;
    const test::MeanSE& fd = f.finiteDifference(k);
    const double mean = grad[k].mean * test::mutation();
    double se = std::sqrt(grad[k].se() * grad[k].se() + fd.se() * fd.se());
    std::printf("component %2zu: gradient %+.4e (se %.1e), finite difference %+.4e (se %.1e)\n", k, mean, grad[k].se(), fd.mean, fd.se());
    EXPECT_NEAR(mean, fd.mean, test::kSigmas * se) << "component " << k;
    test::expectPower("component " + std::to_string(k), se, fd.mean, claim);
  }
}

// Refused when the job's options are read (the engine keeps invariants only).
TEST(PathAdjoint, LongerPathsNeedMethodPt) {
  invr::v1::OptimizationSpec o;
  o.set_method(invr::v1::METHOD_RESTIR);
  o.set_max_depth(3);
  try {
    parseGradientOptions(o, 8, 8);
    ADD_FAILURE() << "max_depth 3 with ReSTIR was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("optimization.max_depth"), std::string::npos) << e.what();
  }
  o.set_method(invr::v1::METHOD_PT);
  EXPECT_EQ(parseGradientOptions(o, 8, 8).maxDepth, 3);
}

}  // namespace
}  // namespace invr
