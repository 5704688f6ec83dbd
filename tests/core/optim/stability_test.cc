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

struct Outcome {
  double initial = 0, pt = 0, restir = 0;  // parameter RMSE at the start and after 150 steps
};

double finalError(const char* scene, invr::v1::GradientMethod method, double* initial) {
  auto job = zooJob(scene);
  job.mutable_optimization()->set_method(method);
  job.mutable_optimization()->set_steps(150);
  job.mutable_optimization()->set_target_spp(64);
  Problem p = buildProblem(job);
  *initial = parameterError(p, p.initial);
  return runLocally(p).history.back().parameterError;
}

// The scene's own job run with PT and with ReSTIR (seed 1), printed for the log.
Outcome ptAndRestir(const char* scene) {
  Outcome o;
  o.pt = finalError(scene, invr::v1::METHOD_PT, &o.initial);
  o.restir = finalError(scene, invr::v1::METHOD_RESTIR, &o.initial);
  std::printf("%s, 150 steps: parameter RMSE %.4f -> pt %.4f, restir %.4f\n", scene, o.initial, o.pt, o.restir);
  return o;
}

TEST(Stability, OnAjarPtDriftsAwayWhileRestirConverges) {
  Outcome o = ptAndRestir("ajar");
  EXPECT_GT(o.pt, 1.03 * o.initial) << "PT no longer drifts: the baseline's failure case moved";
  EXPECT_LT(o.restir, 0.98 * o.initial) << "ReSTIR stopped improving on ajar";
  EXPECT_GT(o.pt / o.restir, 1.05);
}

// On oxalis the dim fill gets 2 % of light selection, so PT's one light sample rarely finds it and
// its gradients for the texels only the fill lights are heavy-tailed enough to bias Adam there:
// PT's error hardly moves while ReSTIR's reused fill samples take it to a third. Seeds 1, 2, 3 at
// 150 steps: PT ended at 0.937-0.963x its starting error, ReSTIR at 0.303-0.304x.
TEST(Stability, OnOxalisPtStallsWhileRestirConverges) {
  Outcome o = ptAndRestir("oxalis");
  EXPECT_GT(o.pt, 0.9 * o.initial) << "PT no longer stalls on oxalis: the baseline's failure case moved";
  EXPECT_LT(o.restir, 0.4 * o.initial) << "ReSTIR stopped converging on oxalis";
  EXPECT_GT(o.pt / o.restir, 2.5);
}

}  // namespace
}  // namespace invr
