// Shared helpers for the statistical tests: running mean/standard error, and scenes from JSON.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "core/io/job_io.h"
#include "core/scene/scene_builder.h"

namespace invr::test {

// Welford accumulator for independent samples.
struct MeanSE {
  double n = 0, mean = 0, m2 = 0;
  void add(double x) {
    n += 1;
    double d = x - mean;
    mean += d / n;
    m2 += d * (x - mean);
  }
  double variance() const { return n > 1 ? m2 / (n - 1) : 0; }
  double se() const { return std::sqrt(variance() / n); }
};

// Every statistical tolerance in the suite is k standard errors with k = 4: a correct estimator
// fails with probability ~6e-5 per check (two-sided normal tail), and seeds are fixed so a run
// is reproducible.
inline constexpr double kSigmas = 4.0;

inline std::unique_ptr<Scene> sceneFromJson(const std::string& sceneJson) {
  auto job = parseJobJson("{\"scene\": " + sceneJson + "}", "test");
  return buildJobScene(job);
}

}  // namespace invr::test
