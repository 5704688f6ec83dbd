// Direct illumination against analytic references: a point light over a diffuse plane, a square
// area light over a point (form factor), and RIS against plain NEE on scenes with many lights.
#include <gtest/gtest.h>

#include "core/render/direct_light.h"
#include "core/render/path_tracer.h"
#include "core/scene/zoo.h"
#include "test_util.h"

namespace invr {
namespace {

constexpr const char* kPointLightScene = R"({
  "materials": [{"name": "plane", "diffuse": {"albedo": {"value": 0.5}}}],
  "shapes": [{"name": "plane", "material": "plane", "quad": {},
              "transform": {"scale": {"x": 10, "y": 10, "z": 1}, "rotate_xyz_degrees": {"x": -90}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0, "y": 2, "z": 0}, "intensity": {"r": 3, "g": 3, "b": 3}}}],
  "views": [{"eye": {"y": 5}, "target": {}, "up": {"z": -1}}]
})";

TEST(DirectLight, PointLightOverDiffusePlaneIsAnalytic) {
  auto scene = test::sceneFromJson(kPointLightScene);
  for (auto est : {LightEstimator::NeeMis, LightEstimator::Ris}) {
    RenderOptions opt;
    opt.estimator = est;
    for (Vec3 p : {Vec3(0.3f, 0, 0.2f), Vec3(-1.5f, 0, 0.7f), Vec3(2.5f, 0, -3.f)}) {
      Sampler s(RngKey{1});
      Rgb L = pathRadiance(*scene, p + Vec3(0, 1, 0), Vec3(0, -1, 0), s, opt);
      // L = rho / pi * I * cos(theta) / r^2 with cos(theta) = h / r.
      double r2 = p.x * p.x + 4.0 + p.z * p.z, r = std::sqrt(r2);
      double expected = 0.5 / M_PI * 3.0 * (2.0 / r) / r2;
      EXPECT_NEAR(L.x, expected, 1e-5 * expected + 1e-7);
    }
  }
}

// Square light of half-side a at height h above the shading point, facing it.
constexpr const char* kAreaLightScene = R"({
  "materials": [{"name": "plane", "diffuse": {"albedo": {"value": 0.6}}},
                {"name": "lamp", "diffuse": {"albedo": {"value": 0}}}],
  "shapes": [{"name": "plane", "material": "plane", "quad": {},
              "transform": {"scale": {"x": 10, "y": 10, "z": 1}, "rotate_xyz_degrees": {"x": -90}}},
             {"name": "lamp", "material": "lamp", "quad": {},
              "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"x": 90}, "translate": {"y": 1}}}],
  "lights": [{"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 2, "g": 2, "b": 2}}}],
  "views": [{"eye": {"y": 5}, "target": {}, "up": {"z": -1}}]
})";

// Differential form factor from a point to a parallel rectangle a x b whose corner is above the
// point at distance c.
double cornerFormFactor(double a, double b, double c) {
  double X = a / c, Y = b / c;
  double sx = std::sqrt(1 + X * X), sy = std::sqrt(1 + Y * Y);
  return (X / sx * std::atan(Y / sx) + Y / sy * std::atan(X / sy)) / (2 * M_PI);
}

TEST(DirectLight, SquareAreaLightMatchesFormFactor) {
  auto scene = test::sceneFromJson(kAreaLightScene);
  // Point below the centre: four corner rectangles of 0.5 x 0.5 at distance 1.
  double F = 4 * cornerFormFactor(0.5, 0.5, 1.0);
  double expected = 0.6 * 2.0 * F;  // L_o = rho * L_e * F
  struct Variant { LightEstimator est; bool vis; const char* name; };
  for (auto v : {Variant{LightEstimator::NeeMis, false, "nee_mis"}, Variant{LightEstimator::Ris, false, "ris"},
                 Variant{LightEstimator::Ris, true, "ris_visibility"}}) {
    RenderOptions opt;
    opt.estimator = v.est;
    opt.risVisibilityInTarget = v.vis;
    opt.risCandidates = 4;
    test::MeanSE m;
    for (int i = 0; i < 40000; ++i) {
      Sampler s(RngKey{2, 0, 0, 0, uint64_t(i)});
      m.add(pathRadiance(*scene, Vec3(0, 0.5f, 0), Vec3(0, -1, 0), s, opt).x);
    }
    m.mean *= test::mutation();
    EXPECT_NEAR(m.mean, expected, test::kSigmas * m.se()) << v.name << " se " << m.se();
    test::expectPower(v.name, m.se(), expected);
  }
}

// RIS must be unbiased against plain NEE + MIS: compare the mean luminance over a pixel set.
void compareRisWithNee(const std::string& zooName, int maxDepth) {
  auto scene = buildScene(zooScene(zooName));
  const Camera& cam = scene->cameras[0];
  auto run = [&](RenderOptions opt) {
    test::MeanSE m;
    for (int py = 4; py < scene->height; py += 8)
      for (int px = 4; px < scene->width; px += 8)
        for (int s = 0; s < 512; ++s) {
          Sampler sampler(RngKey{opt.seed, 0, 0, uint64_t(py * scene->width + px), uint64_t(s)});
          float fx = px + sampler.next1D(), fy = py + sampler.next1D();
          m.add(luminance(pathRadiance(*scene, cam.eye, cam.direction(fx, fy, scene->width, scene->height), sampler, opt)));
        }
    return m;
  };
  RenderOptions nee;
  nee.maxDepth = maxDepth;
  nee.seed = 100;
  auto mNee = run(nee);
  for (bool vis : {false, true}) {
    RenderOptions ris = nee;
    ris.estimator = LightEstimator::Ris;
    ris.risCandidates = 8;
    ris.risVisibilityInTarget = vis;
    ris.seed = 200;
    auto mRis = run(ris);
    double se = std::sqrt(mNee.se() * mNee.se() + mRis.se() * mRis.se());
    EXPECT_NEAR(mRis.mean * test::mutation(), mNee.mean, test::kSigmas * se) << zooName << " visibility " << vis;
    test::expectPower(zooName + (vis ? ", RIS with visibility" : ", RIS") + " against NEE", se, mNee.mean);
  }
}

// streamRis takes its candidates in batches (deferred draws, shadow rays in packets where they
// pay). It must give the numbers of streaming them one by one (Alg. 1 as written, below) exactly:
// the same reservoir, chosen sample and shadow-ray count at every shading point, for both
// samplers, with and without visibility in the target, on scenes whose shadow rays go as packets
// (cornell), one by one (tree), to delta lights only (oxalis) and to an environment (spot).
// With at most 8 lights and 64 candidates the candidates' lights come as counts (a multinomial as
// binomials, light by light), and a delta light's k candidates enter as one of weight k; the loop
// below draws its counts with binomial probabilities of its own (log-gamma) and streams the same
// groups one by one. With more candidates each selects its light, as Alg. 1 writes it.
int binomialByLogGamma(int n, double p, float u) {
  if (!(p > 0.0)) return 0;
  if (p >= 1.0) return n;
  double cdf = 0;
  for (int k = 0; k < n; ++k) {
    cdf += std::exp(std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0) + k * std::log(p) + (n - k) * std::log1p(-p));
    if (double(u) < cdf) return k;
  }
  return n;
}

Reservoir streamRisOneByOne(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, int candidates, bool visibility,
                            PathContext* ctx, LightSample& chosen, Rgb& chosenF, bool& nonFinite) {
  DeltaLightCache deltas;
  Reservoir r;
  if (scene.lights.empty()) return r;
  const Distribution1D& sel = scene.lightSelection();
  const size_t L = scene.lights.size();
  const bool counted = L <= 8 && candidates <= 64;
  std::vector<std::pair<size_t, int>> groups;  // (light, candidates it stands for), in stream order
  if (counted) {
    std::vector<int> counts(L, 0);
    int remaining = candidates;
    for (size_t i = 0; i < L; ++i) {
      double rest = 0;
      for (size_t k = i + 1; k < L; ++k) rest += sel.pmf(k);
      if (i + 1 == L || rest <= 0.0) {
        counts[i] = remaining;
        break;
      }
      const int c = binomialByLogGamma(remaining, sel.pmf(i) / (sel.pmf(i) + rest), sampler.next1D());
      counts[i] = c;
      remaining -= c;
    }
    for (size_t i = 0; i < L; ++i) {
      if (scene.lights[i].isDelta()) {
        if (counts[i] > 0) groups.push_back({i, counts[i]});
      } else {
        for (int k = 0; k < counts[i]; ++k) groups.push_back({i, 1});
      }
    }
  }
  for (int m = 0; counted ? m < int(groups.size()) : m < candidates; ++m) {
    const size_t li = counted ? groups[size_t(m)].first : sel.sample(sampler.next1D());
    const int count = counted ? groups[size_t(m)].second : 1;
    const bool delta = scene.lights[li].isDelta();
    const Vec2 d2 = counted && delta ? Vec2(0.f, 0.f) : sampler.next2D();
    const float uPick = sampler.next1D();
    const float pmf = sel.pmf(li);
    r.M += float(count);
    if (!(pmf > 0.f)) continue;
    DeltaLightCache::Entry* e = delta ? deltas.at(scene, sp, uint32_t(li)) : nullptr;
    LightSample fresh;
    Rgb f(0.f);
    float target;
    if (e) {
      target = e->target;
    } else {
      fresh = sampleLight(scene.lights[li], scene, sp.hit->p, Vec2(d2.y, d2.x), uint32_t(li));
      target = risTarget(sp, fresh, &f);
    }
    const LightSample& ls = e ? e->ls : fresh;
    if (!std::isfinite(target)) {
      nonFinite = true;
      target = 0.f;
    }
    if (target > 0.f && visibility && (e ? DeltaLightCache::occluded(*e, scene, sp, ctx) : traceShadow(scene, sp, ls, ctx)))
      target = 0.f;
    const double w = target > 0.f ? double(count) * double(target) / (double(pmf) * double(ls.pdfNative)) : 0.0;
    if (r.stream(ls.ref, w, target, uPick)) {
      chosen = ls;
      chosenF = e ? e->f : f;
    }
  }
  r.finalize(r.M);
  return r;
}

TEST(DirectLight, BatchedRisCandidatesGiveTheNumbersOfOneByOne) {
  for (const char* name : {"cornell", "tree", "oxalis", "spot"}) {
    auto scene = buildScene(zooScene(name));
    const Camera& cam = scene->cameras[0];
    if (std::string(name) == "cornell") {
      EXPECT_TRUE(scene->accel.shadowPacketsPay());  // packets are compared here
    }
    if (std::string(name) == "tree") {
      EXPECT_FALSE(scene->accel.shadowPacketsPay());  // and single rays here
    }
    int points = 0, chosenCount = 0;
    for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol})
      for (bool visibility : {true, false})
        for (int py = 3; py < scene->height; py += 7)
          for (int px = 5; px < scene->width; px += 7) {
            Sampler s0 = Sampler::forSample(kind, uint64_t(py * scene->width + px) * 977u + 13u, 0);
            const Vec2 film = s0.next2D();
            const Vec3 d = cam.direction(float(px) + film.x, float(py) + film.y, scene->width, scene->height);
            SurfaceHit hit;
            if (!scene->intersect(cam.eye, d, hit)) continue;
            const Bsdf bsdf = scene->materials[size_t(scene->meshMaterial[hit.mesh])].at(hit.uv);
            if (bsdf.isDelta()) continue;
            ShadingPoint sp{&hit, &bsdf, shadingFrame(hit, bsdf, -d), Vec3(), -d};
            sp.wo = sp.frame.toLocal(-d);
            s0.beginDomain(SampleDomain::directLight(0));
            // Batches of every fill and several batches; every fifth point past the counted limit.
            const int candidates = 1 + (px + py) % 19 + ((px / 7 + py / 7) % 5 == 0 ? 64 : 0);
            Sampler s1 = s0, s2 = s0;
            RayStats rays1, rays2;
            PathContext ctx1{&rays1}, ctx2{&rays2};
            LightSample c1, c2;
            Rgb f1(-1.f), f2(-1.f);
            bool bad1 = false, bad2 = false;
            const Reservoir r1 = streamRis(*scene, sp, s1, candidates, visibility, &ctx1, c1, f1, &bad1);
            const Reservoir r2 = streamRisOneByOne(*scene, sp, s2, candidates, visibility, &ctx2, c2, f2, bad2);
            const std::string at = std::string(name) + " " + samplerKindName(kind) + (visibility ? " V" : "") + " pixel " +
                                   std::to_string(px) + "," + std::to_string(py);
            ASSERT_EQ(r1.wSum, r2.wSum) << at;
            ASSERT_EQ(r1.M, r2.M) << at;
            ASSERT_EQ(r1.W, r2.W) << at;
            ASSERT_EQ(r1.targetY, r2.targetY) << at;
            ASSERT_EQ(r1.y.light, r2.y.light) << at;
            ASSERT_EQ(r1.y.tri, r2.y.tri) << at;
            ASSERT_EQ(r1.y.b1, r2.y.b1) << at;
            ASSERT_EQ(r1.y.b2, r2.y.b2) << at;
            ASSERT_EQ(bad1, bad2) << at;
            ASSERT_EQ(rays1.shadow, rays2.shadow) << at;
            ASSERT_EQ(s1.dimension(), s2.dimension()) << at;
            if (r1.W > 0.f) {
              ASSERT_EQ(c1.lightPoint.x, c2.lightPoint.x) << at;
              ASSERT_EQ(c1.wi.y, c2.wi.y) << at;
              ASSERT_EQ(f1.x, f2.x) << at;
              ++chosenCount;
            }
            ++points;
          }
    EXPECT_GT(points, 400) << name;
    EXPECT_GT(chosenCount, points / 8) << name << ": too few lit points for the comparison to mean something";
  }
}

TEST(DirectLight, RisUnbiasedAgainstNeeOnPointAndSpotLights) { compareRisWithNee("oxalis", 1); }
TEST(DirectLight, RisUnbiasedAgainstNeeOnAreaLightsWithBounces) { compareRisWithNee("cornell", 3); }
TEST(DirectLight, RisUnbiasedAgainstNeeOnEnvironmentAndSpot) { compareRisWithNee("spot", 1); }

}  // namespace
}  // namespace invr
