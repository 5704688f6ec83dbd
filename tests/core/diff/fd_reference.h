// The finite-difference reference of the gradient tests: the forward renderer (independent code)
// at theta +- h with common random numbers and sampling distributions frozen at theta. The loss
// is the converged L2 loss, estimated without bias as mean (I_a - T)(I_b - T) over two independent
// renders (a single render's (I - T)^2 adds Var(I), whose derivative is not part of the gradient).
#pragma once

#include <algorithm>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "core/diff/gradient_engine.h"
#include "core/diff/parameters.h"
#include "core/render/renderer.h"
#include "shared_reference.h"
#include "test_util.h"

namespace invr::test {

struct FdReference {
  std::unique_ptr<Scene> scene;
  ParameterRegistry reg;
  std::vector<float> truth, theta;
  Image target;
  RenderOptions options;  // spp and seed are set per render
  int lossSpp = 512;
  int fdSeeds = 4;  // independent central differences averaged per component
  // Per component, the central difference's half step; empty: 2 % of |theta_k| (at least 0.001).
  // Parameters whose truth is 0 (poses) start elsewhere and take a step of their own scale.
  std::vector<float> steps;

  // Registers the parameters, renders the target at the truth, and sets theta = 0.8 truth.
  FdReference(const char* sceneJson, std::initializer_list<const char*> params, RenderOptions o = {}, int lossSamples = 512)
      : scene(sceneFromJson(sceneJson)), options(o), lossSpp(lossSamples) {
    id = sceneJson;
    for (const char* p : params) {
      reg.add(*scene, p);
      id += std::string("|") + p;
    }
    id += "|depth " + std::to_string(o.maxDepth) + " estimator " + std::to_string(int(o.estimator));
    truth = reg.read(*scene);
    target = render(truth, 1024, 5);
    reg.write(truth, *scene);
    theta = truth;
    for (auto& v : theta) v *= 0.8f;
  }
  Image render(const std::vector<float>& t, int spp, uint64_t seed) {
    reg.write(t, *scene, /*refreshSampling=*/false);
    RenderOptions o = options;
    o.spp = spp;
    o.seed = seed;
    return renderView(*scene, 0, o).image;
  }
  double convergedLoss(const std::vector<float>& t, uint64_t seed) {
    Image a = render(t, lossSpp, 2 * seed + 100), b = render(t, lossSpp, 2 * seed + 101);
    double sum = 0;
    for (size_t i = 0; i < a.data().size(); ++i) sum += double(a.data()[i] - target.data()[i]) * double(b.data()[i] - target.data()[i]);
    return sum / double(a.data().size());
  }
  // Central difference of the converged loss in component k, with its standard error. Light
  // selection is set once at theta and kept for both sides, so random numbers stay common.
  // Computed once per build of the test binary (tests/shared_reference.h), whichever test of the
  // scene needs it first.
  const MeanSE& finiteDifference(size_t k) {
    auto it = cache.find(k);
    if (it != cache.end()) return it->second;
    const float h = k < steps.size() ? steps[k] : 0.02f * std::max(0.05f, std::abs(theta[k]));
    std::string where = id;  // theta is part of the key too
    for (float v : theta) where += " " + std::to_string(v);
    char key[160];
    std::snprintf(key, sizeof key, "fd_reference k=%zu h=%a seeds=%d spp=%d|%016llx", k, double(h), fdSeeds, lossSpp,
                  (unsigned long long)detail::fnv1a(where));
    return cache[k] = sharedMeanSE(key, [&] {
      reg.write(theta, *scene);
      MeanSE fd;
      for (uint64_t seed = 0; seed < uint64_t(fdSeeds); ++seed) {
        auto plus = theta, minus = theta;
        plus[k] += h;
        minus[k] -= h;
        fd.add((convergedLoss(plus, seed) - convergedLoss(minus, seed)) / (2.0 * h));
      }
      reg.write(theta, *scene);
      return fd;
    });
  }
  std::string id;  // the scene, parameters and transport: part of every reference's key
  std::map<size_t, MeanSE> cache;
};

// The engine's gradient (options o, view 0) against the finite differences of components
// `checked`: the mean over independent sessions (ReSTIR sessions burn in first, so reservoirs are
// reused) within kSigmas combined standard errors, and a 10 % error visible (power). Sessions run
// until every checked component could see an error of 8 %: 64, then half as many again each
// round, at most 1024; the rule looks at the spread only. `what(k)` names component k.
inline void expectGradientMatchesFiniteDifferences(FdReference& f, const GradientOptions& o, const std::vector<size_t>& checked,
                                                   const std::string& label, const std::function<std::string(size_t)>& what) {
  GradientEngine engine(*f.scene, f.reg, {f.target}, o);
  f.reg.write(f.theta, *f.scene);
  const int burnIn = o.method == GradientMethod::Restir ? 3 : 0;
  std::vector<MeanSE> grad(f.reg.size());
  auto combinedSe = [&](size_t k) {
    const MeanSE& fd = f.finiteDifference(k);
    return std::sqrt(grad[k].se() * grad[k].se() + fd.se() * fd.se());
  };
  int sessions = 0;
  for (int target = 64;; target = std::min(1024, target * 3 / 2)) {
    for (; sessions < target; ++sessions) {
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 1000 + uint64_t(sessions);
      for (int b = 0; b < burnIn; ++b) {
        GradientRequest rb = r;
        rb.renderOnly = true;
        rb.step = uint64_t(b);
        engine.evaluate(rb, session);
      }
      r.step = uint64_t(burnIn);
      auto g = engine.evaluate(r, session).gradient;
      for (size_t k = 0; k < g.size(); ++k) grad[k].add(g[k]);
    }
    bool enough = true;
    for (size_t k : checked) enough = enough && kSigmas * combinedSe(k) <= 0.08 * std::abs(f.finiteDifference(k).mean);
    if (enough || sessions >= 1024) break;
  }
  std::printf("%s: %d sessions\n", label.c_str(), sessions);
  for (size_t k : checked) {
    const MeanSE& fd = f.finiteDifference(k);
    const double mean = grad[k].mean * mutation();
    const double se = combinedSe(k);
    std::printf("%-6s component %4zu (%s): gradient %+.4e (se %.1e), finite difference %+.4e (se %.1e)\n", label.c_str(), k,
                what(k).c_str(), mean, grad[k].se(), fd.mean, fd.se());
    EXPECT_NEAR(mean, fd.mean, kSigmas * se) << label << " component " << k << " (" << what(k) << ")";
    expectPower(label + " component " + std::to_string(k), se, fd.mean);
  }
}

}  // namespace invr::test
