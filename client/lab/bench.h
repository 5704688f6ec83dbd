// The gradient-quality benchmarks as functions, shared by `invr-lab bench ...` and `invr-lab eval`.
// Each returns its report (figures named as in --json).
#pragma once

#include <string>
#include <vector>

#include "client/common/bench_report.h"
#include "invr/v1/job.pb.h"

namespace invr::cli {

// Equal-time gradient error: relative MSE against a high-sample reference, PT vs RIS vs ReSTIR.
struct GradientsArgs {
  std::string scene = "ajar";
  int reps = 32, restirChains = 8, burnIn = 16, refEvaluations = 32, refSpp = 8;
  int neighbours = 0;  // 0: the job's default
  double mCap = 0;
  double radiusPixels = 0;
  int edgeNeighbours = -1;  // shape jobs: edge reservoirs merged per sample; -1: the job's
  bool ablations = true;   // shape jobs: the per-term and edge-importance rows
  int targetSpp = 256;
  std::string sampler;  // empty: the job's (optimization.sampler)
  std::vector<std::string> params;  // --param NAME[=V[,V,V]]: replaces the zoo job's parameters
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
  int stage1History = 0;     // > 0: the stage-1 samplers' maps average this many passes (0: the job's)
  int refresh = 0;           // > 0: steps between stage-1 refreshes (0: the job's)
  int stage1Stride = 0;      // > 0: stage 1's grid stride (0: the job's)
  int levels = 0;            // > 0: adaptive's resolution levels D (0: the job's)
  std::string out;           // folder for each stage-1 sampler's last map of view 0
  bool json = false;
};
BenchReport benchPixelVariance(const PixelBenchArgs& args);

// Variance-aware rendering (Yan et al. 2024) on the zoo's rings, spot and roulette jobs: one report
// per scene (client/lab/bench_variance.cc says what each measures).
struct VarianceBenchArgs {
  std::string scene = "all";
  double seconds = 20;        // rings: per estimator at equal time
  int fdReps = 800;           // rings: central-difference evaluations of the reference
  int fdSpp = 4;              // rings: spp of each render in the reference
  double fdStep = 0.02;       // rings: h (checked against h/2)
  std::vector<int> ksweep = {1, 4, 16, 64};
  int ksweepSteps = 0;        // 0: the job's
  int spotSteps = 0, rouletteSteps = 0;  // 0: the jobs'
  int measureSpp = 64;        // spp of the variance measurements (Bessel per pixel)
  int oracleCells = 8, oracleSpp = 256;
  int overheadSteps = 9;
  uint64_t seed = 11;
  bool json = false;
};
std::vector<BenchReport> benchVariance(const VarianceBenchArgs& args);
VarianceBenchArgs quickVarianceBenchArgs();  // the smoke-test settings of --quick

// Smooth-shades the named shapes of the job's scene (vertex normals; the zoo flat-shades the meshes
// that move), putting the scene inline. Throws InputError naming `flag` for a shape it lacks.
void smoothShadeShapes(v1::JobSpec& job, const std::vector<std::string>& shapes, const std::string& flag);

}  // namespace invr::cli
