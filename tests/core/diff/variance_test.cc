// Variance and its derivatives (Yan et al. 2024) against independent references:
//   - two point lights chosen with probability p (softmax of two logits): per jitter u the
//     estimator's second moment is a(u)^2 / p + b(u)^2 / (1 - p), so
//       V = M_a / p + M_b / (1 - p) - (A + B)^2,  dV/dz_a = p (1 - p) (-M_a / p^2 + M_b / (1 - p)^2),
//     with A = E[a], M_a = E[a^2] over the pixel (measured by tracing each light alone: logits
//     +-20 make one light certain). Through the whole engine (variance pass, primal render as I1).
//     The detached baseline gives exactly 0 for any logit: the known bias.
//   - a rough conductor's roughness, which enters both the BSDF and its sampling density: the
//     second moment's derivative against central differences of E[F^2] with sampling re-derived
//     at alpha +- h and common random numbers (h checked against h/2). The detached estimator
//     must miss it.
//   - Russian-roulette survival per bounce (fixed survival) inside a diffuse box, depth 5: the
//     second moment's derivative for each bounce's survival against central differences with
//     common random numbers.
// Tolerances: |mean - ref| <= 4 combined SE, and 4 SE must be under 10 % of the reference.
#include "core/diff/variance_visitor.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "core/diff/gradient_engine.h"
#include "core/diff/interior_estimator.h"
#include "core/render/renderer.h"
#include "test_util.h"

namespace invr {
namespace {

// A diffuse floor seen from above, lit by two point lights of different strength and distance.
// 4x4 pixels.
constexpr const char* kTwoLights = R"({
  "materials": [{"name": "floor", "diffuse": {"albedo": {"value": 0.6}}}],
  "shapes": [{"name": "floor", "material": "floor", "quad": {}, "transform": {"scale": {"x": 2, "y": 2, "z": 1}}}],
  "lights": [
    {"name": "a", "point": {"position": {"x": -0.6, "z": 1.0}, "intensity": {"r": 1.0, "g": 1.2, "b": 0.8}}},
    {"name": "b", "point": {"position": {"x": 1.2, "y": 0.5, "z": 2.5}, "intensity": {"r": 3.0, "g": 2.0, "b": 2.5}}}
  ],
  "views": [{"eye": {"z": 3}, "target": {}, "fov_y_degrees": 40}],
  "film": {"width": 4, "height": 4}
})";

// One camera sample of pixel (x, y) through `estimator`, as the pass driver traces it.
Rgb traceSample(const Scene& scene, const InteriorEstimator& est, int x, int y, uint64_t seed, uint64_t sample, const VarianceWeights* w,
                PathGradient* grad) {
  const uint64_t pixel = uint64_t(y) * uint64_t(scene.width) + uint64_t(x);
  Sampler sampler(RngKey::withSample(RngKey{seed, 0, 0, pixel, 0}.pixelHash(), sample));
  CameraSampleInput in;
  in.x = x;
  in.y = y;
  in.pixel = pixel;
  in.o = scene.cameras[0].eye;
  in.d = scene.cameras[0].direction(float(x) + sampler.next1D(), float(y) + sampler.next1D(), scene.width, scene.height);
  SampleCounters counters;
  if (w) return est.varianceSample(in, sampler, counters, *w, *grad);
  return est.sample(in, sampler, counters, Rgb(0.f), nullptr, nullptr);
}

double sumEntries(const PathGradient& g, uint32_t index) {
  double s = 0;
  for (const auto& e : g.entries())
    if (e.first == index) s += e.second;
  return s;
}

TEST(Variance, TwoLightSelectionMatchesTheClosedForm) {
  auto scene = test::sceneFromJson(kTwoLights);
  ParameterRegistry reg;
  reg.add(*scene, "sampling/light_logits");
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = 1;
  const int W = scene->width, H = scene->height, N = W * H;

  // Moments of each light alone, per pixel and channel, over the pixel's jitter (common jitter).
  std::vector<double> A(size_t(N) * 3), B(A.size()), Ma(A.size()), Mb(A.size());
  const int kJitter = 4096;
  for (int which = 0; which < 2; ++which) {
    reg.write(which == 0 ? std::vector<float>{20.f, -20.f} : std::vector<float>{-20.f, 20.f}, *scene);
    ASSERT_EQ(scene->lightSelection().pmf(size_t(which)), 1.f);
    auto est = makePtEstimator({*scene, reg, o, 0, 1, nullptr});
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (int s = 0; s < kJitter; ++s) {
          Rgb v = traceSample(*scene, *est, x, y, 7, uint64_t(s), nullptr, nullptr);
          for (int c = 0; c < 3; ++c) {
            size_t i = size_t(y * W + x) * 3 + size_t(c);
            (which == 0 ? A : B)[i] += double(v[c]) / kJitter;
            (which == 0 ? Ma : Mb)[i] += double(v[c]) * v[c] / kJitter;
          }
        }
  }
  const double p = 0.3;
  reg.write({float(std::log(p)), float(std::log(1 - p))}, *scene);
  double V = 0, dV = 0;
  for (size_t i = 0; i < A.size(); ++i) {
    V += Ma[i] / p + Mb[i] / (1 - p) - (A[i] + B[i]) * (A[i] + B[i]);
    dV += p * (1 - p) * (-Ma[i] / (p * p) + Mb[i] / ((1 - p) * (1 - p)));
  }
  // The engine's variance term is (weight / K) * mean over pixels and channels.
  const double norm = 1.0 / (3.0 * N);
  Image target(W, H, 3);
  for (bool detached : {false, true}) {
    o.variance.enabled = true;
    o.variance.detached = detached;
    o.variance.spp = 4;
    o.sppPrimal = 4;
    GradientEngine engine(*scene, reg, {target}, o);
    test::MeanSE grad, term;
    for (int i = 0; i < 400; ++i) {
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 100 + uint64_t(i);
      GradientResult g = engine.evaluate(r, session);
      grad.add(g.gradient[0]);
      term.add(g.stats.variance_term());
      EXPECT_NEAR(g.gradient[0], -g.gradient[1], 1e-6 * (1 + std::abs(g.gradient[0]))) << "softmax: the two logits' derivatives cancel";
    }
    std::printf("%s: dV/dz_a %+.5e (se %.1e), closed form %+.5e; V %.5e (se %.1e), closed form %.5e\n", detached ? "detached" : "unbiased",
                grad.mean, grad.se(), dV * norm, term.mean, term.se(), V * norm);
    term.mean *= test::mutation();
    EXPECT_NEAR(term.mean, V * norm, test::kSigmas * term.se()) << "the variance estimate";
    test::expectPower(std::string(detached ? "detached" : "unbiased") + ": the variance estimate", term.se(), V * norm);
    if (detached) {
      EXPECT_EQ(grad.mean, 0.0) << "the detached baseline never sees a sampling probability";
      EXPECT_GT(std::abs(dV * norm), 0.0);
    } else {
      grad.mean *= test::mutation();
      EXPECT_NEAR(grad.mean, dV * norm, test::kSigmas * grad.se());
      test::expectPower("unbiased: dV/dz_a", grad.se(), dV * norm);
    }
  }
}

// A rough metal plate under a small area light and a dim sky: roughness enters f and its
// sampling density (BSDF sampling with MIS against the light).
constexpr const char* kGlossy = R"({
  "materials": [
    {"name": "metal", "rough_conductor": {"roughness": {"value": 0.3}}},
    {"name": "lamp", "diffuse": {"albedo": {"value": 0.5}}}
  ],
  "shapes": [
    {"name": "plate", "material": "metal", "quad": {}, "transform": {"scale": {"x": 2, "y": 2, "z": 1}}},
    {"name": "lamp", "material": "lamp", "quad": {},
     "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"x": 180}, "translate": {"x": -0.4, "z": 1.2}}}
  ],
  "lights": [
    {"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 10, "g": 9, "b": 8}}},
    {"name": "sky", "constant_environment": {"radiance": {"r": 0.2, "g": 0.2, "b": 0.25}}}
  ],
  "views": [{"eye": {"x": 0.6, "y": 0.2, "z": 3}, "target": {}, "fov_y_degrees": 35}],
  "film": {"width": 4, "height": 4}
})";

// dE[F^2]/dtheta_index summed over pixels and channels: the variance visitor (mean 0, adjoint 1:
// dV^ = 2 F dF + F^2 S), unbiased and detached, against central differences of E[F^2] with
// sampling re-derived at theta +- h and common random numbers, at h and h/2.
struct SecondMomentCheck {
  test::MeanSE fd, fdHalf, unbiased, detached;
};
SecondMomentCheck secondMomentAgainstFiniteDifferences(Scene& scene, const ParameterRegistry& reg, const GradientOptions& o,
                                                       const std::vector<float>& theta, size_t index, float h, int samples) {
  const int W = scene.width, H = scene.height;
  auto momentSums = [&](const std::vector<float>& at) {
    reg.write(at, scene);
    auto est = makePtEstimator({scene, reg, o, 0, 1, nullptr});
    std::vector<double> sums(static_cast<size_t>(samples));
    for (int s = 0; s < samples; ++s)
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          Rgb v = traceSample(scene, *est, x, y, 11, uint64_t(s), nullptr, nullptr);
          sums[size_t(s)] += double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
        }
    return sums;
  };
  SecondMomentCheck c;
  for (float step : {h, h / 2}) {
    auto plus = theta, minus = theta;
    plus[index] += step;
    minus[index] -= step;
    std::vector<double> fp = momentSums(plus), fm = momentSums(minus);
    for (int s = 0; s < samples; ++s) (step == h ? c.fd : c.fdHalf).add((fp[size_t(s)] - fm[size_t(s)]) / (2.0 * double(step)));
  }
  reg.write(theta, scene);
  auto est = makePtEstimator({scene, reg, o, 0, 1, nullptr});
  for (bool detached : {false, true}) {
    VarianceWeights w;
    w.adjoint = Rgb(1.f);
    w.detached = detached;
    PathGradient g;
    for (int s = 0; s < samples; ++s) {
      double sum = 0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          g.clear();
          traceSample(scene, *est, x, y, 23, uint64_t(s), &w, &g);
          sum += sumEntries(g, uint32_t(index));
        }
      (detached ? c.detached : c.unbiased).add(sum);
    }
  }
  std::printf("dE[F^2]: finite differences %+.5e (se %.1e), at h/2 %+.5e (se %.1e); unbiased %+.5e (se %.1e), detached %+.5e (se %.1e)\n",
              c.fd.mean, c.fd.se(), c.fdHalf.mean, c.fdHalf.se(), c.unbiased.mean, c.unbiased.se(), c.detached.mean, c.detached.se());
  return c;
}

// The unbiased estimator within 4 combined SE of the reference (finite differences at h/2, h
// checked against it), with power; the detached one either biased (> 6 SE) or, where no density
// depends on theta, equal to the unbiased one.
enum class Detached { Biased, Unbiased };
void expectSecondMoment(const SecondMomentCheck& c, Detached detached) {
  EXPECT_NEAR(c.fd.mean, c.fdHalf.mean, test::kSigmas * std::hypot(c.fd.se(), c.fdHalf.se())) << "h is not small enough";
  const double se = std::hypot(c.unbiased.se(), c.fdHalf.se());
  EXPECT_NEAR(c.unbiased.mean * test::mutation(), c.fdHalf.mean, test::kSigmas * se);
  test::expectPower("dE[F^2]: unbiased against FD(h/2)", se, c.fdHalf.mean);
  const double seDetached = std::hypot(c.detached.se(), c.fdHalf.se());
  if (detached == Detached::Biased) {
    EXPECT_GT(std::abs(c.detached.mean - c.fdHalf.mean), 6 * seDetached) << "the detached baseline should be biased here";
  } else if (detached == Detached::Unbiased) {
    EXPECT_NEAR(c.detached.mean, c.unbiased.mean, 1e-9 * (1 + std::abs(c.unbiased.mean)));
  }
}

GradientOptions directPt() {
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = 1;
  return o;
}

TEST(Variance, RoughnessSecondMomentMatchesFiniteDifferences) {
  auto scene = test::sceneFromJson(kGlossy);
  ParameterRegistry reg;
  reg.add(*scene, "materials/metal/roughness");
  expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), {0.3f}, 0, 0.02f, 1 << 16), Detached::Biased);
}

// The same plate in rough plastic: its albedo sets the probability of sampling the specular lobe
// (a mixture density), besides the diffuse base.
TEST(Variance, PlasticAlbedoMixtureSecondMomentMatchesFiniteDifferences) {
  std::string json = kGlossy;
  json.replace(json.find(R"("rough_conductor": {"roughness": {"value": 0.3}})"), std::string(R"("rough_conductor": {"roughness": {"value": 0.3}})").size(),
               R"("rough_plastic": {"albedo": {"value": 0.2}, "roughness": {"value": 0.2}})");
  auto scene = test::sceneFromJson(json);
  ParameterRegistry reg;
  reg.add(*scene, "materials/metal/albedo");
  // A dark base: the specular share f / (f + (1 - f) lum) stays inside its clamp [0.1, 0.9].
  expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), {0.2f, 0.2f, 0.2f}, 1, 0.05f, 1 << 16), Detached::Biased);
}

// Control: a diffuse albedo enters no density here (no lobe choice; both lights' selection by
// logits, not by power), so the detached estimator must equal the unbiased one.
TEST(Variance, DensityFreeParameterLeavesTheDetachedEstimatorUnbiased) {
  std::string json = kGlossy;
  json.replace(json.find(R"("rough_conductor": {"roughness": {"value": 0.3}})"), std::string(R"("rough_conductor": {"roughness": {"value": 0.3}})").size(),
               R"("diffuse": {"albedo": {"value": 0.5}})");
  auto scene = test::sceneFromJson(json);
  scene->sampling.lightLogits = {0.f, 0.f};
  scene->updateLightSelection();
  ParameterRegistry reg;
  reg.add(*scene, "materials/metal/albedo");
  expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), {0.5f, 0.5f, 0.5f}, 0, 0.05f, 1 << 15), Detached::Unbiased);
}

// Light selection by power depends on every light's intensity: the lamp's intensity enters F and
// the selection pmf, with MIS between the lamp and the sky.
TEST(Variance, PowerSelectionIntensitySecondMomentMatchesFiniteDifferences) {
  auto scene = test::sceneFromJson(kGlossy);
  ParameterRegistry reg;
  reg.add(*scene, "lights/lamp/intensity");
  const std::vector<float> theta = reg.read(*scene);
  expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), theta, 1, 2.f, 1 << 16), Detached::Biased);
}

// Global and per-pixel selection logits with MIS on: pdf-only parameters, so the detached
// estimator gives 0 while the second moment moves.
TEST(Variance, SelectionLogitsWithMisMatchFiniteDifferences) {
  {
    auto scene = test::sceneFromJson(kGlossy);
    ParameterRegistry reg;
    reg.add(*scene, "sampling/light_logits");
    expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), {0.5f, -0.5f}, 0, 0.1f, 1 << 16), Detached::Biased);
  }
  {
    auto scene = test::sceneFromJson(kGlossy);
    ParameterRegistry reg;
    ParameterOptions map;
    map.mapWidth = 2;  // two cells of 2x4 pixels, 2 lights each
    map.mapHeight = 1;
    reg.add(*scene, "sampling/pixel_light_logits/0", map);
    std::vector<float> theta = reg.read(*scene);
    ASSERT_EQ(theta.size(), 4u);
    theta[0] += 0.4f;  // the cells differ
    theta[2] -= 0.4f;
    expectSecondMoment(secondMomentAgainstFiniteDifferences(*scene, reg, directPt(), theta, 2, 0.3f, 1 << 17), Detached::Biased);
  }
}

// Inside a diffuse box lit by a point light: every path bounces until roulette or depth 5 ends it.
constexpr const char* kBox = R"({
  "materials": [{"name": "walls", "diffuse": {"albedo": {"value": 0.7}}}],
  "shapes": [{"name": "box", "material": "walls", "box": {}, "transform": {"scale": {"x": 2, "y": 2, "z": 2}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0.5, "y": 1.2, "z": -0.5}, "intensity": {"r": 2, "g": 2, "b": 2}}}],
  "views": [{"eye": {"z": 1.5}, "target": {"z": -1}, "fov_y_degrees": 60}],
  "film": {"width": 2, "height": 2}
})";

TEST(Variance, RouletteSurvivalMatchesFiniteDifferences) {
  auto scene = test::sceneFromJson(kBox);
  scene->sampling.survival = {1.f, 0.8f, 0.6f, 0.7f, 0.9f};
  ParameterRegistry reg;
  reg.add(*scene, "sampling/rr_survival");
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = 5;
  const std::vector<float> q = reg.read(*scene);
  const int W = scene->width, H = scene->height, kSamples = 1 << 19;
  auto momentSum = [&](const InteriorEstimator& est, int s) {
    double sum = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        Rgb v = traceSample(*scene, est, x, y, 31, uint64_t(s), nullptr, nullptr);
        sum += double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
      }
    return sum;
  };
  VarianceWeights w;
  w.adjoint = Rgb(1.f);
  reg.write(q, *scene);
  auto est = makePtEstimator({*scene, reg, o, 0, 1, nullptr});
  std::vector<test::MeanSE> d(q.size());
  PathGradient g;
  for (int s = 0; s < kSamples; ++s) {
    std::vector<double> sum(q.size(), 0.0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        g.clear();
        traceSample(*scene, *est, x, y, 37, uint64_t(s), &w, &g);
        for (size_t k = 0; k < q.size(); ++k) sum[k] += sumEntries(g, uint32_t(k));
      }
    for (size_t k = 0; k < q.size(); ++k) d[k].add(sum[k]);
  }
  for (size_t k : {size_t(1), size_t(2)}) {
    const float h = 0.04f;
    auto plus = q, minus = q;
    plus[k] += h;
    minus[k] -= h;
    reg.write(plus, *scene);
    auto ep = makePtEstimator({*scene, reg, o, 0, 1, nullptr});
    std::vector<double> fp(static_cast<size_t>(kSamples));
    for (int s = 0; s < kSamples; ++s) fp[size_t(s)] = momentSum(*ep, s);
    reg.write(minus, *scene);
    auto em = makePtEstimator({*scene, reg, o, 0, 1, nullptr});
    test::MeanSE fd;
    for (int s = 0; s < kSamples; ++s) fd.add((fp[size_t(s)] - momentSum(*em, s)) / (2.0 * h));
    const double se = std::hypot(d[k].se(), fd.se());
    std::printf("survival of bounce %zu: dE[F^2]/dq %+.5e (se %.1e), finite difference %+.5e (se %.1e)\n", k + 1, d[k].mean, d[k].se(), fd.mean,
                fd.se());
    EXPECT_NEAR(d[k].mean * test::mutation(), fd.mean, test::kSigmas * se) << "bounce " << k + 1;
    test::expectPower("survival of bounce " + std::to_string(k + 1), se, fd.mean);
  }
}

// What one walk gathers after m bounces (emission at, and NEE from, vertex m): the part of F that
// needs m survival decisions. Fixed survival 1 draws no random number, so this is the walk
// without roulette.
struct BounceGroups {
  std::vector<Rgb> g = std::vector<Rgb>(8, Rgb(0.f));
  int bounces = 0;
  void emission(Rgb weight, Rgb Le, const LightSampleRef&, float) { g[size_t(bounces)] += weight * Le; }
  void direct(Rgb beta, const DirectPath& p, const WalkVertex& v) { g[size_t(v.depth)] += beta * p.contribution(); }
  void bounce(const WalkVertex&, Vec3) { ++bounces; }
};

TEST(Variance, RouletteSecondMomentMatchesTheClosedForm) {
  // With fixed survival q_j after vertex j, F = sum_m g_m 1[the path reached m] / Q_m with
  // Q_m = prod_{j<m} q_j, so E[F^2] = sum_{m,n} E[g_m . g_n] / Q_min(m,n) and
  //   dE[F^2]/dq_j = -sum_{min(m,n) > j} E[g_m . g_n] / (Q_min(m,n) q_j).
  // E[g_m . g_n] is measured on walks without roulette; the second moment with roulette and the
  // variance visitor's derivative must match the closed form.
  auto scene = test::sceneFromJson(kBox);
  const std::vector<float> q = {1.f, 0.8f, 0.6f, 0.7f, 0.9f};
  const int depth = 5, W = scene->width, H = scene->height, kSamples = 1 << 18;
  WalkSettings walk;
  walk.maxDepth = depth;
  walk.bsdfMis = true;
  auto Q = [&](int m) {
    double p = 1;
    for (int j = 0; j < m; ++j) p *= q[size_t(j)];
    return p;
  };
  // Per sample (summed over pixels): the closed form's second moment and derivative.
  scene->sampling.survival.assign(q.size(), 1.f);
  test::MeanSE closed;
  std::vector<test::MeanSE> closedD(q.size());
  for (int s = 0; s < kSamples; ++s) {
    double m2 = 0;
    std::vector<double> d(q.size(), 0.0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        Sampler sampler(RngKey::withSample(RngKey{41, 0, 0, uint64_t(y * W + x), 0}.pixelHash(), uint64_t(s)));
        Vec3 dir = scene->cameras[0].direction(float(x) + sampler.next1D(), float(y) + sampler.next1D(), W, H);
        BounceGroups v;
        NeeMisDirect direct{*scene, nullptr};
        walkPath(*scene, scene->cameras[0].eye, dir, sampler, walk, direct, v, nullptr);
        for (int m = 0; m <= depth; ++m)
          for (int n = 0; n <= depth; ++n) {
            const Rgb& a = v.g[size_t(m)];
            const Rgb& b = v.g[size_t(n)];
            const double gg = double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z;
            const int lo = std::min(m, n);
            m2 += gg / Q(lo);
            for (int j = 0; j < lo; ++j) d[size_t(j)] -= gg / (Q(lo) * q[size_t(j)]);
          }
      }
    closed.add(m2);
    for (size_t j = 0; j < q.size(); ++j) closedD[j].add(d[j]);
  }
  // With roulette: the second moment by plain walks, and its derivative by the variance visitor.
  scene->sampling.survival = q;
  ParameterRegistry reg;
  reg.add(*scene, "sampling/rr_survival");
  GradientOptions o = directPt();
  o.maxDepth = depth;
  auto est = makePtEstimator({*scene, reg, o, 0, 1, nullptr});
  VarianceWeights w;
  w.adjoint = Rgb(1.f);
  test::MeanSE measured;
  std::vector<test::MeanSE> visitor(q.size());
  PathGradient g;
  for (int s = 0; s < kSamples; ++s) {
    double m2 = 0;
    std::vector<double> sum(q.size(), 0.0);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        Rgb v = traceSample(*scene, *est, x, y, 43, uint64_t(s), nullptr, nullptr);
        m2 += double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
        g.clear();
        traceSample(*scene, *est, x, y, 47, uint64_t(s), &w, &g);
        for (size_t j = 0; j < q.size(); ++j) sum[j] += sumEntries(g, uint32_t(j));
      }
    measured.add(m2);
    for (size_t j = 0; j < q.size(); ++j) visitor[j].add(sum[j]);
  }
  std::printf("E[F^2] with roulette %.5e (se %.1e), closed form %.5e (se %.1e)\n", measured.mean, measured.se(), closed.mean, closed.se());
  EXPECT_NEAR(measured.mean * test::mutation(), closed.mean, test::kSigmas * std::hypot(measured.se(), closed.se()));
  test::expectPower("E[F^2] with roulette", std::hypot(measured.se(), closed.se()), closed.mean);
  for (size_t j = 0; j < 4; ++j) {  // q_4 only gates emission at vertex 5, and the box's light is a point
    const double se = std::hypot(visitor[j].se(), closedD[j].se());
    std::printf("survival after vertex %zu: dE[F^2]/dq %+.5e (se %.1e), closed form %+.5e (se %.1e)\n", j, visitor[j].mean, visitor[j].se(),
                closedD[j].mean, closedD[j].se());
    EXPECT_NEAR(visitor[j].mean * test::mutation(), closedD[j].mean, test::kSigmas * se) << "survival " << j;
    // q_3 gates only the last bounce's light, a small part of E[F^2]: compared for its sign and
    // size, with no claim of power (10 % would take minutes).
    if (j < 3) test::expectPower("survival after vertex " + std::to_string(j), se, closedD[j].mean);
  }
}

// The engine's gradient of the whole variance-aware loss, mean over seeds, against central
// differences of the engine's own loss estimate with common random numbers (every pass's stream
// shared between theta + h and theta - h).
struct LossCheck {
  test::MeanSE gradient, fd, biasTerm, varianceTerm;
};
LossCheck lossAgainstFiniteDifferences(Scene& scene, const ParameterRegistry& reg, const GradientOptions& o, const Image& target,
                                       std::vector<float> theta, size_t index, float h, int evaluations) {
  GradientEngine engine(scene, reg, {target}, o);
  LossCheck c;
  auto evaluate = [&](const std::vector<float>& at, uint64_t seed) {
    reg.write(at, scene);
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.seed = seed;
    return engine.evaluate(r, session);
  };
  for (int i = 0; i < evaluations; ++i) {
    GradientResult g = evaluate(theta, 1000 + uint64_t(i));
    c.gradient.add(g.gradient[index]);
    c.biasTerm.add(g.stats.bias_term());
    c.varianceTerm.add(g.stats.variance_term());
    auto plus = theta, minus = theta;
    plus[index] += h;
    minus[index] -= h;
    c.fd.add((evaluate(plus, 5000 + uint64_t(i)).stats.loss() - evaluate(minus, 5000 + uint64_t(i)).stats.loss()) / (2.0 * double(h)));
  }
  reg.write(theta, scene);
  return c;
}

TEST(Variance, VarianceAwareLossGradientMatchesFiniteDifferencesOfTheLoss) {
  // L = L_bias + (lambda / K) V over a rough metal plate's roughness, with a target rendered at
  // another roughness so that both terms pull.
  auto scene = test::sceneFromJson(kGlossy);
  ParameterRegistry reg;
  reg.add(*scene, "materials/metal/roughness");
  GradientOptions o = directPt();
  o.sppPrimal = o.sppGradient = 16;
  o.variance.enabled = true;
  o.variance.samples = 16;
  o.variance.spp = 16;
  reg.write({0.15f}, *scene);
  RenderOptions ro;
  ro.spp = 1 << 14;
  Image target = renderView(*scene, 0, ro).image;
  LossCheck c = lossAgainstFiniteDifferences(*scene, reg, o, target, {0.3f}, 0, 0.04f, 3000);
  const double se = std::hypot(c.gradient.se(), c.fd.se());
  std::printf("dL/dalpha %+.5e (se %.1e), finite differences of the loss %+.5e (se %.1e); bias term %.3e, variance term %.3e\n",
              c.gradient.mean, c.gradient.se(), c.fd.mean, c.fd.se(), c.biasTerm.mean, c.varianceTerm.mean);
  EXPECT_NEAR(c.gradient.mean * test::mutation(), c.fd.mean, test::kSigmas * se);
  test::expectPower("dL/dalpha", se, c.fd.mean);
  EXPECT_GT(c.varianceTerm.mean, 0.2 * c.biasTerm.mean) << "the variance term should matter here";
}

TEST(Variance, TimeAwareLossGradientMatchesFiniteDifferencesOfTheLoss) {
  // L* = L_bias + lambda* t V (Eq. 33) over one bounce's survival in the diffuse box: t (rays per
  // sample, Eq. 36) and V both depend on it, in opposite directions.
  auto scene = test::sceneFromJson(kBox);
  scene->sampling.survival = {1.f, 0.8f, 0.6f, 0.7f, 0.9f};
  ParameterRegistry reg;
  reg.add(*scene, "sampling/rr_survival");
  GradientOptions o = directPt();
  o.maxDepth = 5;
  o.sppPrimal = o.sppGradient = 64;
  o.variance.enabled = true;
  o.variance.cost = VarianceCost::Depth;
  o.variance.weight = 0.5;
  o.variance.spp = 64;
  Image target(scene->width, scene->height, 3);
  const std::vector<float> q = reg.read(*scene);
  LossCheck c = lossAgainstFiniteDifferences(*scene, reg, o, target, q, 1, 0.1f, 3000);
  const double se = std::hypot(c.gradient.se(), c.fd.se());
  std::printf("dL*/dq_2 %+.5e (se %.1e), finite differences of the loss %+.5e (se %.1e); variance term %.3e\n", c.gradient.mean,
              c.gradient.se(), c.fd.mean, c.fd.se(), c.varianceTerm.mean);
  EXPECT_NEAR(c.gradient.mean * test::mutation(), c.fd.mean, test::kSigmas * se);
  test::expectPower("dL*/dq_2", se, c.fd.mean);
}

}  // namespace
}  // namespace invr
