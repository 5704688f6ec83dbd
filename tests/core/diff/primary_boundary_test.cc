// The primary boundary term alone against an analytic case: a diffuse quad facing the camera under
// a constant environment, moving in depth. Its radiance albedo * Le does not depend on where it
// is (the interior derivative is zero), so the whole derivative of the image is the boundary's:
// with a unit adjoint, d/dz of sum_p I_p = d(area in pixels)/dz * (albedo - 1) * Le per channel.
#include "core/diff/primary_boundary.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <tbb/task_arena.h>

#include "test_util.h"

namespace invr {
namespace {

using test::kSigmas;
using test::MeanSE;

const char* kQuadScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}}],
  "shapes": [{"name": "q", "quad": {}, "material": "grey"}],
  "lights": [{"name": "sky", "constant_environment": {"radiance": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "fov_y_degrees": 40}],
  "film": {"width": 64, "height": 64}})";

struct QuadCase {
  std::unique_ptr<Scene> scene = test::sceneFromJson(kQuadScene);
  ParameterRegistry reg;
  std::vector<EdgeTopology> topology;
  GradientOptions options;
  QuadCase(GradientMethod method) {
    reg.add(*scene, "shapes/q/translation");
    reg.write(reg.read(*scene), *scene);
    topology.resize(scene->meshes.size());
    topology[0] = EdgeTopology::build(scene->meshes[0]);
    options.method = method;
    options.maxDepth = 1;
  }
  // One estimate of d(sum over pixels and channels of I)/dtheta with `samples` edge samples.
  std::vector<double> estimate(int samples, uint64_t seed, BoundaryPassStats* stats = nullptr) {
    EstimatorSetup es{*scene, reg, options, 0, 1, nullptr};
    auto estimator = options.method == GradientMethod::Pt ? makePtEstimator(es) : makeRisEstimator(es);
    Image adjoint(scene->width, scene->height, 3);
    for (auto& v : adjoint.data()) v = 1.f;
    GradientScratchPool scratch(reg.size());
    std::vector<double> g(reg.size(), 0.0);
    PrimaryBoundary boundary(*scene, reg, topology);
    BoundaryPassStats st = boundary.run({0, adjoint, *estimator, samples, seed, 0, scratch, g});
    if (stats) *stats = st;
    return g;
  }
};

TEST(PrimaryBoundary, QuadMovingInDepthMatchesTheAnalyticAreaDerivative) {
  // Area of the quad on the film at distance d: (2 * (H/2) / (tan(fov/2) d))^2 pixels.
  const double H = 64, tanHalf = std::tan(20.0 * 3.14159265358979 / 180.0), d = 4.0;
  const double dAreaDz = 2.0 * H * H / (tanHalf * tanHalf * d * d * d);  // moving towards the eye
  const double expected = 3.0 * dAreaDz * (0.5 - 1.0);
  for (GradientMethod method : {GradientMethod::Pt, GradientMethod::Ris}) {
    QuadCase s(method);
    MeanSE z, x, y;
    BoundaryPassStats st;
    for (uint64_t seed = 0; seed < 16; ++seed) {
      auto g = s.estimate(4000, 1000 + seed, &st);
      x.add(g[0]);
      y.add(g[1]);
      z.add(g[2]);
    }
    // From the eye the quad's 4 rim edges are silhouettes (boundary edges); the diagonal is not.
    EXPECT_EQ(st.candidateEdges, 4u);
    EXPECT_NEAR(st.filmLength, 4 * 2 * H / (2 * tanHalf * d), 1e-2);
    SCOPED_TRACE(gradientMethodName(method));
    z.mean *= test::mutation();
    std::printf("%s: dI/dz %.3f +- %.3f (analytic %.3f); dI/dx %.3f +- %.3f\n", gradientMethodName(method), z.mean, z.se(), expected, x.mean,
                x.se());
    EXPECT_NEAR(z.mean, expected, kSigmas * z.se()) << "SE " << z.se();
    const std::string m = gradientMethodName(method);
    test::expectPower(m + ": dI/dz", z.se(), expected);
    // Sideways the pixel sum does not change while the quad stays on the film: zero, where a
    // sideways derivative a tenth the size of dI/dz would show.
    EXPECT_NEAR(x.mean, 0.0, kSigmas * x.se() + 1e-9);
    EXPECT_NEAR(y.mean, 0.0, kSigmas * y.se() + 1e-9);
    test::expectPower(m + ": dI/dx = 0, against the size of dI/dz", x.se(), expected);
    test::expectPower(m + ": dI/dy = 0, against the size of dI/dz", y.se(), expected);
  }
}

TEST(PrimaryBoundary, SameNumbersForAnyThreadCount) {
  QuadCase s(GradientMethod::Pt);
  auto a = s.estimate(3000, 7);
  std::vector<double> b;
  {
    tbb::task_arena one(1);
    one.execute([&] { b = s.estimate(3000, 7); });
  }
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace invr
