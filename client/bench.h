// The gradient-quality benchmarks as functions, shared by `invr bench ...` and `invr eval`.
// Each returns its report (figures named as in --json).
#pragma once

#include <string>

#include "client/bench_report.h"

namespace invr::cli {

// Equal-time gradient error: relative MSE against a high-sample reference, PT vs RIS vs ReSTIR.
struct GradientsArgs {
  std::string scene = "ajar";
  int reps = 32, restirChains = 8, burnIn = 16, refEvaluations = 32, refSpp = 8;
  int neighbours = 0;  // 0: the job's default
  double mCap = 0;
  double radiusPixels = 0;
  int targetSpp = 256;
  bool json = false;
};
BenchReport benchGradients(const GradientsArgs& args);

// ReSTIR's overhead over RIS at equal sample counts.
struct OverheadArgs {
  std::string scene = "oxalis";
  int steps = 30;  // medians of interleaved steps: the machine is shared and noisy
  int targetSpp = 64;
  bool json = false;
};
BenchReport benchOverhead(const OverheadArgs& args);

// Gradient variance per pixel sampler at equal path budget.
struct PixelBenchArgs {
  std::string scene = "mirror";
  int reps = 1024;
  double defensive = 0;  // override the job's uniform share
  int samples = 0;       // pixel samples per view; 0: a fifth of the pixels
  int targetSpp = 0;     // 0: the job's
  double thetaFraction = 1;  // theta = truth + f (initial - truth)
  int referenceSamples = 0;  // > 0: also measure with maps from this many stage-1 passes per pixel
  std::string loss;          // empty: the job's
  bool json = false;
};
BenchReport benchPixelVariance(const PixelBenchArgs& args);

}  // namespace invr::cli
