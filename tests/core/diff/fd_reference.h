// The finite-difference reference of the gradient tests: the forward renderer (independent code)
// at theta +- h with common random numbers and sampling distributions frozen at theta. The loss
// is the converged L2 loss, estimated without bias as mean (I_a - T)(I_b - T) over two independent
// renders (a single render's (I - T)^2 adds Var(I), whose derivative is not part of the gradient).
#pragma once

#include <algorithm>
#include <map>
#include <memory>
#include <vector>

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
    const float h = 0.02f * std::max(0.05f, std::abs(theta[k]));
    char key[128];
    std::snprintf(key, sizeof key, "fd_reference k=%zu h=%a seeds=%d spp=%d|%016llx", k, double(h), fdSeeds, lossSpp,
                  (unsigned long long)detail::fnv1a(id));
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

}  // namespace invr::test
