// Whole gradient-engine steps of parameters that move visibility (shapes, cameras) against
// finite differences of the converged loss: the case (scene, one parameter, target, theta), its
// validated reference and the engine's estimate run to the power a claim needs. Shared by
// shape_gradient_test.cc and camera_pose_test.cc.
//
// Reference (fd): the forward renderer (independent code) at theta +- h with common random
// numbers (the same seeds on both sides), loss mean (I_a - T)(I_b - T) from two independent
// renders. Trust: the central difference is computed at h and at h/2 with the same seeds and the
// two must agree (Richardson: a curvature or topology event inside [theta - h, theta + h] would
// separate them). Estimate: the engine's gradient averaged over independent sessions. Check
// |mean - fd| <= 4 sqrt(se^2 + se_fd^2), with the power to see the claimed error.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "core/diff/gradient_engine.h"
#include "core/render/renderer.h"
#include "core/stopwatch.h"
#include "shared_reference.h"
#include "test_util.h"

namespace invr::test {

// How a case's target and references are rendered. The target's noise enters the estimate and
// the reference alike (the same image), so it moves neither's mean apart: 256 samples a pixel. RIS
// over 16 candidates, each with its shadow ray, keeps the references' soft shadows clean; with
// point and spot lights only there is little to choose between, and NEE's one shadow ray per light
// gives the image for less. (The knot's diagnoses keep the settings their documented figures were
// measured with: 1024 samples, RIS throughout.)
struct ReferenceSettings {
  int targetSpp = 256;
  bool neeForDeltaLights = true;
};

struct ShapeCase {
  std::unique_ptr<Scene> scene;
  ParameterRegistry reg;
  std::vector<float> truth, theta;
  Image target;
  RenderOptions ro;
  std::string id;  // what the case is (scene, parameter, rendering): part of its references' keys
  ShapeCase(const std::string& json, const char* param, std::vector<float> offset)
      : ShapeCase(test::sceneFromJson(json.c_str()), param, std::move(offset), json) {}
  ShapeCase(std::unique_ptr<Scene> s, const char* param, std::vector<float> offset, const std::string& what, ReferenceSettings rs = {})
      : scene(std::move(s)) {
    id = what + "|" + param + "|target " + std::to_string(rs.targetSpp);
    reg.add(*scene, param);
    truth = reg.read(*scene);
    bool deltaOnly = rs.neeForDeltaLights;
    for (const Light& l : scene->lights) deltaOnly = deltaOnly && (l.kind == LightKind::Point || l.kind == LightKind::Spot);
    ro.estimator = deltaOnly ? LightEstimator::NeeMis : LightEstimator::Ris;
    ro.risCandidates = 16;
    ro.risVisibilityInTarget = true;
    id += deltaOnly ? "|nee" : "|ris16";
    target = render(truth, rs.targetSpp, 77);
    theta = truth;
    for (size_t i = 0; i < theta.size(); ++i) theta[i] += offset[i];
    reg.write(theta, *scene);
  }
  Image render(const std::vector<float>& t, int spp, uint64_t seed, RenderOptions::Window window = {}) {
    reg.write(t, *scene);
    RenderOptions o = ro;
    o.spp = spp;
    o.seed = seed;
    o.window = window;
    return renderView(*scene, 0, o).image;
  }
  // The unbiased L2 loss (two independent images) over the pixels of `fdWindow`, normalised by the
  // whole film: a pixel outside it is the same on both sides of a difference (its samples are its
  // own, and nothing it sees moves), so its terms cancel and a difference of these losses is the
  // difference of the whole film's.
  RenderOptions::Window fdWindow;
  // Per-pixel loss weights (empty: every pixel 1), for losses over a class of pixels; the engine's
  // estimates take the same weights as a loss mask (GradientOptions::lossMasks). Part of `id`.
  std::vector<float> pixelWeights;
  double loss(const std::vector<float>& t, uint64_t seed) {
    Image a = render(t, 128, 2 * seed + 1000, fdWindow), b = render(t, 128, 2 * seed + 1001, fdWindow);
    const RenderOptions::Window w = fdWindow.empty() ? RenderOptions::Window{0, 0, a.width(), a.height()} : fdWindow;
    double sum = 0;
    for (int y = w.y0; y < w.y1; ++y)
      for (int x = w.x0; x < w.x1; ++x)
        for (int ch = 0; ch < 3; ++ch) {
          const size_t i = (size_t(y) * size_t(a.width()) + size_t(x)) * 3 + size_t(ch);
          const double w = pixelWeights.empty() ? 1.0 : double(pixelWeights[size_t(y) * size_t(a.width()) + size_t(x)]);
          sum += w * double(a.data()[i] - target.data()[i]) * double(b.data()[i] - target.data()[i]);
        }
    return sum / double(a.data().size());
  }
  std::vector<float> shifted(size_t k, float h) const {
    std::vector<float> t = theta;
    if (along.empty()) t[k] += h;
    else
      for (size_t j = 0; j < t.size(); ++j) t[j] += h * along[j];
    return t;
  }
  // The pixels a move of +-h changes in a difference's first seed, both images (exact equality:
  // the sides share their samples), as a box 3 pixels wider on every side for the seeds whose
  // samples reach a little further. Empty when nothing changes (the difference is then 0 anyway).
  RenderOptions::Window changedPixels(size_t k, float h) {
    const std::vector<float> plus = shifted(k, h), minus = shifted(k, -h);
    RenderOptions::Window box{1 << 30, 1 << 30, -1, -1};
    for (uint64_t s : {uint64_t(1000), uint64_t(1001)}) {
      const Image a = render(plus, 128, s), b = render(minus, 128, s);
      for (int y = 0; y < a.height(); ++y)
        for (int x = 0; x < a.width(); ++x)
          if (a.rgb(x, y).x != b.rgb(x, y).x || a.rgb(x, y).y != b.rgb(x, y).y || a.rgb(x, y).z != b.rgb(x, y).z) {
            box.x0 = std::min(box.x0, x), box.y0 = std::min(box.y0, y);
            box.x1 = std::max(box.x1, x + 1), box.y1 = std::max(box.y1, y + 1);
          }
    }
    reg.write(theta, *scene);
    if (box.x1 < 0) return {0, 0, 0, 0};
    constexpr int kPad = 3;
    return {std::max(0, box.x0 - kPad), std::max(0, box.y0 - kPad), std::min(target.width(), box.x1 + kPad),
            std::min(target.height(), box.y1 + kPad)};
  }
  // A direction in theta (vertex parameters): when set, fd() and the engine's estimates are the
  // derivative along it instead of component k, so every vertex's derivative counts with its sign.
  std::vector<float> along;
  // Central differences of the converged loss in component k (or along `along`), one per seed:
  // seed s renders both sides with the same random numbers.
  std::vector<double> fdPerSeed(size_t k, float h, int seeds) {
    std::vector<double> out;
    const std::vector<float> plus = shifted(k, h), minus = shifted(k, -h);
    for (uint64_t seed = 0; seed < uint64_t(seeds); ++seed)
      out.push_back((loss(plus, seed) - loss(minus, seed)) / (2.0 * double(h)));
    reg.write(theta, *scene);
    return out;
  }
  // ReSTIR sessions first render `burnIn` steps, the b-th at theta - (burnIn - b) * approach: with
  // a non-zero approach the reservoirs it reuses were created in other geometries.
  MeanSE engine(size_t k, const GradientOptions& o, int sessions, std::vector<float> approach = {}) {
    std::vector<double> g = perSession(k, o, sessions, std::move(approach));
    MeanSE m;
    for (double v : g) m.add(v);
    return m;
  }
  // The same sessions (seeds) under two options: their difference, with the noise they share taken out.
  MeanSE pairedDifference(size_t k, const GradientOptions& a, const GradientOptions& b, int sessions, const std::vector<float>& approach) {
    const std::vector<double> ga = perSession(k, a, sessions, approach), gb = perSession(k, b, sessions, approach);
    MeanSE m;
    for (size_t i = 0; i < ga.size(); ++i) m.add(ga[i] - gb[i]);
    return m;
  }
  // Sessions first, first + 1, ... (each its own seed).
  std::vector<double> perSession(size_t k, const GradientOptions& o, int sessions, std::vector<float> approach, int first = 0) {
    GradientEngine engine(*scene, reg, {target}, o);
    reg.write(theta, *scene);
    std::vector<double> out;
    const int burnIn = o.method == GradientMethod::Restir ? 2 : 0;
    for (int i = first; i < first + sessions; ++i) {
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 5000 + uint64_t(i);
      for (int b = 0; b < burnIn; ++b) {
        // Whole steps (not render-only burn-in), so the boundary terms' edge reservoirs are made too.
        GradientRequest rb = r;
        rb.step = uint64_t(b);
        auto before = theta;
        for (size_t j = 0; j < approach.size(); ++j) before[j] -= float(burnIn - b) * approach[j];
        reg.write(before, *scene);
        engine.evaluate(rb, session);
      }
      reg.write(theta, *scene);
      r.step = uint64_t(burnIn);
      const std::vector<double> g = engine.evaluate(r, session).gradient;
      double d = 0;
      if (along.empty()) d = g[k];
      else
        for (size_t j = 0; j < g.size(); ++j) d += g[j] * double(along[j]);
      out.push_back(d);
    }
    return out;
  }
};

inline GradientOptions shapeOptions(GradientMethod method) {
  GradientOptions o;
  o.method = method;
  o.sppPrimal = 2;
  o.sppGradient = 2;
  o.restir.candidates = 8;
  o.boundary.samples = 1024;
  return o;
}

struct Check {
  MeanSE est, fd;
  bool agrees() const { return std::abs(est.mean - fd.mean) <= kSigmas * combined(); }
  double combined() const { return std::sqrt(est.se() * est.se() + fd.se() * fd.se()); }
};

// The reference for one component: central differences at h and at h/2 with the same seeds, from
// the binary's shared references (tests/shared_reference.h: computed once, whichever test needs
// it first). Trust: a curvature or topology event inside [theta - h, theta + h] would separate the
// two. Their per-seed gap (common random numbers take most of the noise out) estimates 3/4 of the
// reference's own truncation error, which must stay below a third of the smallest error the
// comparison claims to see: |gap| <= 4 SE + 2 % of the derivative, with the power to see a gap of
// 10 %. The engine's sessions are cheap next to a reference: a reference gets the seeds its noise
// needs (its SE is printed beside the estimate's), and the sessions give each comparison the rest
// of its power. A diagnosis (`claimsPower` false) measures and prints, and claims no power: the
// knot's back fill lights so little of what the camera sees that its reference is mostly noise.
inline MeanSE validatedFd(ShapeCase& c, size_t k, float h, const char* what, int seeds = 4, bool claimsPower = true) {
  char key[160];
  std::snprintf(key, sizeof key, "shape fd k=%zu h=%a seeds=%d|", k, double(h), seeds);
  std::string description = std::string(key) + c.id + "|theta";
  for (float t : c.theta) description += " " + std::to_string(t);
  description += "|along";
  for (float a : c.along) description += " " + std::to_string(a);
  char hash[40];
  std::snprintf(hash, sizeof hash, "%016llx", (unsigned long long)test::detail::fnv1a(description));
  const Stopwatch clock;
  const std::vector<double> v = test::sharedReference(std::string(key) + hash, [&] {
    c.fdWindow = c.changedPixels(k, h);
    std::vector<double> both = c.fdPerSeed(k, h, seeds), half = c.fdPerSeed(k, h / 2, seeds);
    both.insert(both.end(), half.begin(), half.end());
    const RenderOptions::Window w = c.fdWindow;
    both.push_back(double(w.x1 - w.x0) * double(w.y1 - w.y0) / (double(c.target.width()) * double(c.target.height())));
    c.fdWindow = {};
    return both;
  });
  MeanSE a, b, gap;
  for (int s = 0; s < seeds; ++s) {
    a.add(v[size_t(s)]);
    b.add(v[size_t(seeds + s)]);
    gap.add(v[size_t(s)] - v[size_t(seeds + s)]);
  }
  std::printf("%s: fd(h=%g) %+.4e (se %.1e), fd(h/2) %+.4e (se %.1e), %d seeds over %.0f %% of the film (%.1f s)\n", what, double(h), a.mean,
              a.se(), b.mean, b.se(), seeds, 100 * v[size_t(2 * seeds)], clock.seconds());
  EXPECT_LE(std::abs(gap.mean), kSigmas * gap.se() + 0.02 * std::abs(a.mean)) << what << ": h and h/2 disagree by " << gap.mean;
  const std::string gapWhat = std::string(what) + ", the reference at h against h/2";
  const double gapSe = gap.se() + 0.02 * std::abs(a.mean) / kSigmas;
  if (claimsPower) test::expectPower(gapWhat, gapSe, a.mean);
  else std::printf("%s: power %.1f %% (a diagnosis: printed, not claimed)\n", gapWhat.c_str(), 100 * kSigmas * gapSe / std::abs(a.mean));
  return a;
}

inline Check report(Check r, const char* what, double seconds) {
  r.est.mean *= test::mutation();
  std::printf("%-44s gradient %+.4e (se %.1e, %d sessions, %.1f ms each)  fd %+.4e (se %.1e)  %s\n", what, r.est.mean, r.est.se(), int(r.est.n),
              1e3 * seconds / r.est.n, r.fd.mean, r.fd.se(), r.agrees() ? "agree" : "DIFFER");
  return r;
}

// The estimate over a fixed number of sessions (the ablations, which must differ from FD).
inline Check run(ShapeCase& c, size_t k, const MeanSE& fd, const GradientOptions& o, int sessions, const char* what,
          std::vector<float> approach = {}) {
  const Stopwatch clock;
  MeanSE est = c.engine(k, o, sessions, std::move(approach));
  return report(Check{est, fd}, what, clock.seconds());
}

// The estimate over as many sessions as it takes (at most `maxSessions`) for the comparison to
// see an error of 0.8 * claim of share * FD: below what the test claims (10 % unless it says why
// not), so that an error of that size fails (INVR_TEST_MUTATE). It stops early once the estimate's
// SE is under half the reference's (more sessions would barely help: the reference needs more
// seeds). After 32 sessions each round goes straight to the count the spread so far predicts
// (SE falls as 1/sqrt(n)), a tenth more for the spread's own noise, at least a quarter and at most
// four times more than before: geometric growth overshot by a quarter on average. The sessions are
// seeded in order, and the rule looks at the spread only, never at the agreement, so the verdict
// is a fixed function of the code. A case the cap cannot bring there fails its power check.
inline Check runToPower(ShapeCase& c, size_t k, const MeanSE& fd, const GradientOptions& o, const char* what, std::vector<float> approach = {},
                 double share = 1.0, int maxSessions = 2048, double claim = 0.10) {
  const Stopwatch clock;
  Check r{MeanSE{}, fd};
  int n = 32;
  while (true) {
    for (double g : c.perSession(k, o, n - int(r.est.n), approach, int(r.est.n))) r.est.add(g);
    const double allowed = 0.8 * claim * std::abs(share * fd.mean) / kSigmas;  // combined SE to stop at
    if (r.combined() <= allowed || r.est.se() <= 0.5 * fd.se() || n >= maxSessions) break;
    const double room = allowed * allowed - fd.se() * fd.se();
    const double target = std::max(room > 0 ? std::sqrt(room) : 0.0, 0.5 * fd.se());
    const double predicted = 1.1 * n * (r.est.se() / target) * (r.est.se() / target);
    n = std::min(maxSessions, int(std::clamp(std::ceil(predicted), 1.25 * n, 4.0 * n)));
  }
  return report(r, what, clock.seconds());
}

// Agreement with FD, with the power to see a `claim` error in the whole derivative.
inline void expectMatches(const Check& r, const char* what, double claim = 0.10) {
  EXPECT_TRUE(r.agrees()) << what << ": " << r.est.mean << " vs fd " << r.fd.mean;
  test::expectPower(what, r.combined(), r.fd.mean, claim);
}

// For a case where one term carries `share` of the derivative: the power to see a 10 % error in
// that term (a 10 % error in it moves the estimate by 10 % of share * FD).
inline void expectTermPower(const Check& r, const char* what, double share = 1.0) {
  test::expectPower(std::string(what) + ", the term alone", r.combined(), share * r.fd.mean);
}

// For a case where one term carries most of the derivative but not all: its share (one minus the
// estimate with the term switched off, `without`, over FD), which must be over 80 %, then PT with
// the power to see a 10 % error in that share.
inline void expectTermCarries(ShapeCase& c, size_t k, const MeanSE& fd, const GradientOptions& without, const char* what,
                       int withoutSessions = 64) {
  const Check w = run(c, k, fd, without, withoutSessions, (std::string(what) + ", without the term").c_str());
  const double share = 1.0 - w.est.mean / fd.mean;
  std::printf("%s: the term is %.1f %% of the derivative\n", what, 100 * share);
  EXPECT_GT(share, 0.8) << what << ": the term should carry the derivative here";
  const Check r = runToPower(c, k, fd, shapeOptions(GradientMethod::Pt), what, {}, std::max(share, 0.1));
  expectMatches(r, what);
  expectTermPower(r, what, share);
}


}  // namespace invr::test
