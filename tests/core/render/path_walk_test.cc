// The shared walk (core/render/path_walk.h), as the gradient engine's interior estimators run it
// through the pass driver, against an independent path tracer (reference_path_tracer.h), region
// by region: the same estimator of the same image, so every region's means agree within their
// standard errors, which come from each pixel's own spread over independent repetitions. The
// comparison has power: 4 standard errors are under 5 % of most regions' radiance.
#include "core/render/path_walk.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "core/diff/diff_scenes.h"
#include "core/diff/pass_driver.h"
#include "core/render/reference_path_tracer.h"
#include "test_util.h"

namespace invr {
namespace {

void compareWithReference(const char* sceneJson, GradientMethod method, int depth) {
  auto scene = test::sceneFromJson(sceneJson);
  const int W = scene->width, H = scene->height, reps = 48, spp = 16;
  ParameterRegistry none;
  GradientOptions o;
  o.method = method;
  o.maxDepth = depth;
  GradientScratchPool scratch(0);
  auto estimator = method == GradientMethod::Pt ? makePtEstimator({*scene, none, o, 0, spp, nullptr})
                                                 : makeRisEstimator({*scene, none, o, 0, spp, nullptr});
  test::PixelStats walk(W, H), reference(W, H);
  RenderOptions ro;
  ro.maxDepth = depth;
  ro.estimator = method == GradientMethod::Pt ? LightEstimator::NeeMis : LightEstimator::Ris;
  ro.risCandidates = o.restir.candidates;
  ro.risVisibilityInTarget = o.restir.visibilityInTarget;
  const Camera& cam = scene->cameras[0];
  for (int r = 0; r < reps; ++r) {
    PassSpec spec;
    spec.stream = uint64_t(r);
    spec.spp = spp;
    walk.add(runPass(*scene, *estimator, spec, scratch).image);
    Image im(W, H, 3);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        Rgb acc(0.f);
        for (int i = 0; i < spp; ++i) {
          Sampler s(RngKey{7000 + uint64_t(r), 0, 0, uint64_t(y * W + x), uint64_t(i)});
          Vec3 d = cam.direction(float(x) + s.next1D(), float(y) + s.next1D(), W, H);
          acc += test::referencePathRadiance(*scene, cam.eye, d, s, ro);
        }
        im.setRgb(x, y, acc / float(spp));
      }
    reference.add(im);
  }
  test::RegionComparison c = test::compareRegions(walk, reference, 5);
  std::vector<double> rel = c.relativeSe;
  std::sort(rel.begin(), rel.end());
  std::printf("%s depth %d: %zu regions, max |z| %.2f, mean z^2 %.2f, median relative SE %.3f\n", gradientMethodName(method), depth,
              c.z.size(), c.maxAbsZ(), c.meanZ2(), rel[rel.size() / 2]);
  ASSERT_GE(c.z.size(), 20u);
  // 24-48 regions: a |z| above 4.5 has probability 3e-4 at most for a correct estimator.
  EXPECT_LT(c.maxAbsZ(), 4.5);
  // Mean z^2 is 1 for matching estimators (sd sqrt(2/24) = 0.3 at most): this catches a spread
  // of small biases that no single region shows.
  EXPECT_GT(c.meanZ2(), 0.2);
  EXPECT_LT(c.meanZ2(), 2.2);
  // Power: in three regions of four, 4 SE is at most 5 % of the region's radiance (5 %, not 10 %:
  // a region's error is a bias of the whole walk there).
  test::expectPower(std::string(gradientMethodName(method)) + ": three regions in four", rel[rel.size() * 3 / 4], 1.0, 0.05);
}

TEST(PathWalk, PtMatchesAnIndependentPathTracerThroughAReflection) {
  compareWithReference(test::kReflectionScene, GradientMethod::Pt, 3);
}
TEST(PathWalk, PtDirectMatchesAnIndependentPathTracer) { compareWithReference(test::kDiffScene, GradientMethod::Pt, 1); }
TEST(PathWalk, RisMatchesAnIndependentPathTracer) { compareWithReference(test::kDiffScene, GradientMethod::Ris, 1); }

}  // namespace
}  // namespace invr
