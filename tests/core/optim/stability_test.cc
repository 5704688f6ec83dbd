// Where the paper's baseline fails, a test shows it (Wang et al. 2023, §7): on `ajar` (a painting
// lit through a nearly closed door) one light sample per pixel gives gradients so noisy that
// Adam walks the texture away from the truth, while ReSTIR's reused reservoirs keep improving it.
// Seeds are fixed, so the run is deterministic. The margins come from three seeds (1, 2, 3) at
// 150 steps: PT ended at 1.051-1.056x its starting error, ReSTIR at 0.937-0.960x with nearest-
// neighbour reuse and 0.88-0.91x since reuse tries a random nearby pixel's reservoir first (ratio
// 1.10-1.12, now 1.16 on seed 1); the asserted margins leave room on either side.
#include <gtest/gtest.h>

#include <cstdio>

#include "core/diff/zoo_jobs.h"
#include "core/optim/local_run.h"

namespace invr {
namespace {

double finalError(const char* scene, invr::v1::GradientMethod method, double* initial) {
  auto job = zooJob(scene);
  job.mutable_optimization()->set_method(method);
  job.mutable_optimization()->set_steps(150);
  job.mutable_optimization()->set_target_spp(64);
  Problem p = buildProblem(job);
  *initial = parameterError(p, p.initial);
  return runLocally(p).history.back().parameterError;
}

TEST(Stability, OnAjarPtDriftsAwayWhileRestirConverges) {
  double initial = 0;
  double pt = finalError("ajar", invr::v1::METHOD_PT, &initial);
  double restir = finalError("ajar", invr::v1::METHOD_RESTIR, &initial);
  std::printf("ajar, 150 steps: parameter RMSE %.4f -> pt %.4f, restir %.4f\n", initial, pt, restir);
  EXPECT_GT(pt, 1.03 * initial) << "PT no longer drifts: the baseline's failure case moved";
  EXPECT_LT(restir, 0.98 * initial) << "ReSTIR stopped improving on ajar";
  EXPECT_GT(pt / restir, 1.05);
}

// On oxalis the dim fill gets 2 % of light selection, so PT's one light sample rarely finds it and
// its gradients for the texels only the fill lights are heavy-tailed enough to bias Adam there:
// PT's error hardly moves while ReSTIR's reused fill samples take it to a third. Seeds 1, 2, 3 at
// 150 steps: PT ended at 0.937-0.963x its starting error, ReSTIR at 0.303-0.304x.
TEST(Stability, OnOxalisPtStallsWhileRestirConverges) {
  double initial = 0;
  double pt = finalError("oxalis", invr::v1::METHOD_PT, &initial);
  double restir = finalError("oxalis", invr::v1::METHOD_RESTIR, &initial);
  std::printf("oxalis, 150 steps: parameter RMSE %.4f -> pt %.4f, restir %.4f\n", initial, pt, restir);
  EXPECT_GT(pt, 0.9 * initial) << "PT no longer stalls on oxalis: the baseline's failure case moved";
  EXPECT_LT(restir, 0.4 * initial) << "ReSTIR stopped converging on oxalis";
  EXPECT_GT(pt / restir, 2.5);
}

}  // namespace
}  // namespace invr
