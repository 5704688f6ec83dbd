// What ReSTIR guarantees where the paper's baselines fail (Wang et al. 2023, §7): its reused
// reservoirs keep the gradients clean enough that Adam converges on `ajar` (a painting lit
// through a nearly closed door) and `oxalis` (texels lit only by a dim fill light). The tests
// assert ReSTIR's convergence; the baseline's failure (PT drifting or stalling) is printed and
// recorded as a figure of the run (`pt_ratio` in the test's XML), not asserted: it is the
// baseline's behaviour, and a better baseline is not a regression of ours. Seeds are fixed, so the
// run is deterministic; the margins below come from seeds 1, 2 and 3 at 150 steps.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "core/job/zoo_jobs.h"
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

// ReSTIR at 150 steps ended at 0.88-0.91x the starting error (seeds 1-3); PT at 1.05x (it drifts).
TEST(Stability, OnAjarRestirConverges) {
  Outcome o = ptAndRestir("ajar");
  ::testing::Test::RecordProperty("pt_ratio", std::to_string(o.pt / o.initial));
  ::testing::Test::RecordProperty("restir_ratio", std::to_string(o.restir / o.initial));
  EXPECT_LT(o.restir, 0.96 * o.initial) << "ReSTIR stopped improving on ajar";
}

// On oxalis the dim fill gets 2 % of light selection, so PT's one light sample rarely finds it and
// its gradients for the texels only the fill lights are heavy-tailed (PT's error hardly moves:
// 0.94-0.96x). ReSTIR's reused fill samples take it to 0.30x.
TEST(Stability, OnOxalisRestirConverges) {
  Outcome o = ptAndRestir("oxalis");
  ::testing::Test::RecordProperty("pt_ratio", std::to_string(o.pt / o.initial));
  ::testing::Test::RecordProperty("restir_ratio", std::to_string(o.restir / o.initial));
  EXPECT_LT(o.restir, 0.4 * o.initial) << "ReSTIR stopped converging on oxalis";
}

}  // namespace
}  // namespace invr
