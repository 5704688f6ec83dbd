// The point-light shadow boundary alone against an analytic case: a square card between a point
// light and a floor, moving sideways. The camera looks straight down at the floor from beside the
// light, so the floor maps to the film by a uniform scale k and sees both shadow borders. The
// reference is the derivative of the lit floor's integral under the moving shadow, a 1-D
// quadrature along the two borders that move:
//   d/dx0 sum_p I_p = -3 k^2 m [∫ L(x_R, y) dy - ∫ L(x_L, y) dy]   (3 channels, unit adjoint)
// with m the shadow's magnification and L the unshadowed floor radiance (rho/pi) I cos / r^2.
#include "core/diff/delta_shadow_boundary.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdio>

#include "test_util.h"

namespace invr {
namespace {

using test::kSigmas;
using test::MeanSE;

const char* kCardScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 5, "y": 5, "z": 1}}},
    {"name": "card", "quad": {}, "material": "grey", "transform": {"scale": {"x": 0.25, "y": 0.25, "z": 1}, "translate": {"x": 0.2, "z": 2}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 2, "z": 4}, "intensity": {"r": 10, "g": 10, "b": 10}}}],
  "views": [{"eye": {"z": 6}, "target": {}, "fov_y_degrees": 60}],
  "film": {"width": 64, "height": 64}})";

struct CardCase {
  std::unique_ptr<Scene> scene = test::sceneFromJson(kCardScene);
  ParameterRegistry reg;
  std::vector<EdgeTopology> topology;
  GradientOptions options;
  explicit CardCase(const char* parameter) {
    reg.add(*scene, parameter);
    reg.write(reg.read(*scene), *scene);
    for (const auto& m : scene->meshes) topology.push_back(EdgeTopology::build(m));
    options.method = GradientMethod::Pt;
    options.maxDepth = 1;
  }
  std::vector<double> estimate(int samples, uint64_t seed) {
    auto estimator = makePtEstimator({*scene, reg, options, 0, 1, nullptr});
    Image adjoint(scene->width, scene->height, 3);
    for (auto& v : adjoint.data()) v = 1.f;
    GradientScratchPool scratch(reg.size());
    std::vector<double> g(reg.size(), 0.0);
    DeltaShadowBoundary(*scene, reg, topology).run({0, adjoint, *estimator, samples, seed, 0, scratch, g});
    return g;
  }
};

double floorRadiance(double x, double y) {
  const double dx = x - 2.0, r2 = dx * dx + y * y + 16.0, r = std::sqrt(r2);
  return 0.5 / 3.14159265358979 * 10.0 * (4.0 / r) / r2;
}

// Simpson's rule along a border x = const, y in [-0.5, 0.5].
double alongBorder(double x) {
  const int n = 2000;
  const double h = 1.0 / n;
  double sum = floorRadiance(x, -0.5) + floorRadiance(x, 0.5);
  for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * floorRadiance(x, -0.5 + i * h);
  return sum * h / 3.0;
}

TEST(DeltaShadowBoundary, CardMovingSidewaysMatchesTheBorderQuadrature) {
  const double k = 32.0 / (std::tan(30.0 * 3.14159265358979 / 180.0) * 6.0);  // pixels per floor unit
  const double m = 2.0;                                                       // light at 4, card at 2
  // Card x in [-0.05, 0.45] -> shadow x in [2 * -0.05 - 2, 2 * 0.45 - 2] = [-2.1, -1.1].
  const double expected = -3.0 * k * k * m * (alongBorder(-1.1) - alongBorder(-2.1));
  CardCase c("shapes/card/translation");
  MeanSE x, y, z;
  for (uint64_t seed = 0; seed < 16; ++seed) {
    auto g = c.estimate(20000, 500 + seed);
    x.add(g[0]);
    y.add(g[1]);
    z.add(g[2]);
  }
  x.mean *= test::mutation();
  std::printf("d/dx0 %.4f +- %.4f (quadrature %.4f); d/dy0 %.4f +- %.4f\n", x.mean, x.se(), expected, y.mean, y.se());
  EXPECT_NEAR(x.mean, expected, kSigmas * x.se());
  test::expectPower("d/dx0", x.se(), expected);
  // Sideways in y the shadow stays over the same symmetric radiance: zero, where a y derivative a
  // tenth the size of the x one would show.
  EXPECT_NEAR(y.mean, 0.0, kSigmas * y.se() + 1e-9);
  test::expectPower("d/dy0 = 0, against the size of d/dx0", y.se(), expected);
}

// Simpson's rule along the border y = 0.5, x in [x0, x1].
double alongTop(double x0, double x1) {
  const int n = 2000;
  const double h = (x1 - x0) / n;
  double sum = floorRadiance(x0, 0.5) + floorRadiance(x1, 0.5);
  for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * floorRadiance(x0 + i * h, 0.5);
  return sum * h / 3.0;
}

// The receiver moves: the floor rises towards the light and the camera (the card stays). A shadow
// point is l + s (card point - l) with s(z) = (4 - z) / 2 (ds/dz = -1/2: the shadow shrinks), and
// the film scale k(z) = c / (6 - z) grows (dk/dz = k / 6), so each border point's film velocity is
// k (X / 6 + dX/dz) for its floor coordinate X; the term is -∮ L v_out dl over the shadow's rim.
TEST(DeltaShadowBoundary, ReceiverMovingMatchesTheBorderQuadrature) {
  const double k = 32.0 / (std::tan(30.0 * 3.14159265358979 / 180.0) * 6.0);
  const double xR = -1.1, xL = -2.1, dxR = -(0.45 - 2.0) * 0.5, dxL = -(-0.05 - 2.0) * 0.5, dTop = -0.25 * 0.5;
  const double right = k * (xR / 6 + dxR) * k * alongBorder(xR);
  const double left = -k * (xL / 6 + dxL) * k * alongBorder(xL);
  const double topAndBottom = 2.0 * k * (0.5 / 6 + dTop) * k * alongTop(xL, xR);
  const double expected = -3.0 * (right + left + topAndBottom);
  CardCase c("shapes/floor/translation");
  MeanSE z;
  // The four borders nearly cancel (the total is a tenth of each): 16 x 600000 samples for 10 %.
  for (uint64_t seed = 0; seed < 16; ++seed) z.add(c.estimate(600000, 700 + seed)[2]);
  z.mean *= test::mutation();
  std::printf("d/dz_floor %.4f +- %.4f (quadrature %.4f)\n", z.mean, z.se(), expected);
  EXPECT_NEAR(z.mean, expected, kSigmas * z.se());
  test::expectPower("d/dz_floor", z.se(), expected);
}

TEST(DeltaShadowBoundary, SameNumbersForAnyThreadCount) {
  CardCase c("shapes/card/translation");
  auto a = c.estimate(3000, 3);
  std::vector<double> b;
  tbb::task_arena one(1);
  one.execute([&] { b = c.estimate(3000, 3); });
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace invr
