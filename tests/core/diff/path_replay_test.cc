// Path replay (multi-bounce derivatives) against finite differences of the converged loss, on a
// scene where the wall's albedo and the sphere's roughness are seen only through a glossy mirror.
// Reference: the forward path tracer (independent code, NEE + MIS, same depth) at theta +- h with
// common random numbers; the check is |mean - fd| <= 4 sqrt(se_mean^2 + se_fd^2), as for the
// direct-illumination estimators (gradient_engine_test.cc).
#include "core/diff/path_replay.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "core/diff/diff_scenes.h"
#include "core/diff/fd_reference.h"
#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/render/path_tracer.h"
#include "core/render/renderer.h"

namespace invr {
namespace {

constexpr int kDepth = 3;
constexpr int kSessions = 256;

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
                    256) {}
};

TEST(PathReplay, RadianceMatchesTheForwardPathTracer) {
  // Same estimator, different code: the mean images agree within their standard errors.
  ReplayFixture f;
  f.reg.write(f.truth, *f.scene);
  Image ref = f.render(f.truth, 512, 77);
  PathReplaySettings s;
  s.maxDepth = kDepth;
  const Camera& cam = f.scene->cameras[0];
  double sumRef = 0, sumReplay = 0, sumSq = 0;
  const int spp = 512;
  for (int y = 0; y < f.scene->height; ++y)
    for (int x = 0; x < f.scene->width; ++x) {
      double acc = 0;
      for (int i = 0; i < spp; ++i) {
        Sampler sampler(RngKey{9, 0, 0, uint64_t(y * f.scene->width + x), uint64_t(i)});
        Vec3 d = cam.direction(float(x) + sampler.next1D(), float(y) + sampler.next1D(), f.scene->width, f.scene->height);
        double l = luminance(pathReplayRadiance(*f.scene, cam.eye, d, sampler, s));
        acc += l;
        sumSq += l * l;
      }
      sumReplay += acc / spp;
      sumRef += luminance(ref.rgb(x, y));
    }
  double n = double(f.scene->width * f.scene->height);
  double meanSample = sumReplay / n;
  double var = sumSq / (n * spp) - meanSample * meanSample;
  double se = std::sqrt(var / (n * spp)) * std::sqrt(2.0);  // both images carry this much noise
  EXPECT_NEAR(sumReplay / n, sumRef / n, test::kSigmas * se);
}

TEST(PathReplay, GradientsMatchFiniteDifferencesThroughAReflection) {
  ReplayFixture f;
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = kDepth;
  o.sppPrimal = 4;
  o.sppGradient = 16;
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  std::vector<test::MeanSE> grad(f.reg.size());
  for (int i = 0; i < kSessions; ++i) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = 2000 + uint64_t(i);
    auto g = engine.evaluate(f.theta, r, session).gradient;
    for (size_t k = 0; k < g.size(); ++k) grad[k].add(g[k]);
  }
  // The comparison must have power: the combined SE resolves a 30 % error, or 60 % for the
  // sphere's roughness, whose effect reaches the image only through the mirror's glossy lobe
  // (enough to catch a sign error or a factor of two, at a test time of seconds).
  for (size_t k : {size_t(0), size_t(4), size_t(48), size_t(49), size_t(50)}) {
    const double power = k == 49 ? 0.6 : 0.3;
    const test::MeanSE& fd = f.finiteDifference(k);
    double se = std::sqrt(grad[k].se() * grad[k].se() + fd.se() * fd.se());
    std::printf("component %2zu: gradient %+.4e (se %.1e), finite difference %+.4e (se %.1e)\n", k, grad[k].mean, grad[k].se(), fd.mean,
                fd.se());
    EXPECT_NEAR(grad[k].mean, fd.mean, test::kSigmas * se) << "component " << k;
    EXPECT_LT(test::kSigmas * se, power * std::abs(fd.mean)) << "component " << k << ": the comparison has no power";
  }
}

TEST(PathReplay, LongerPathsNeedMethodPt) {
  ReplayFixture f;
  GradientOptions o;
  o.method = GradientMethod::Restir;
  o.maxDepth = 3;
  EXPECT_THROW(GradientEngine engine(*f.scene, f.reg, {f.target}, o), InputError);
}

}  // namespace
}  // namespace invr
