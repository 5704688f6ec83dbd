// What ReSTIR guarantees where the paper's baselines fail (Wang et al. 2023, §7): its reused
// reservoirs keep the gradients clean enough that Adam converges on `ajar` (a painting lit
// through a nearly closed door) and `oxalis` (texels lit only by a dim fill light). The tests
// assert ReSTIR's convergence; the baseline's failure (PT drifting or stalling) is printed and
// recorded as a figure of the deep suite's run (`pt_ratio` in the test's XML), not asserted: it
// is the baseline's behaviour, and a better baseline is not a regression of ours. Seeds are fixed, so the
// run is deterministic; the margins below come from seeds 1, 2 and 3 at 150 steps.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "core/job/zoo_jobs.h"
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

// ReSTIR at 150 steps ended at 0.88-0.91x the starting error (seeds 1-3); PT at 1.05x (it drifts,
// StabilityDeep.AjarPtBaseline).
TEST(Stability, OnAjarRestirConverges) {
  double initial = 0;
  const double restir = finalError("ajar", invr::v1::METHOD_RESTIR, &initial);
  std::printf("ajar, 150 steps: parameter RMSE %.4f -> restir %.4f\n", initial, restir);
  ::testing::Test::RecordProperty("restir_ratio", std::to_string(restir / initial));
  EXPECT_LT(restir, 0.96 * initial) << "ReSTIR stopped improving on ajar";
}

// On oxalis the dim fill gets 2 % of light selection, so PT's one light sample rarely finds it and
// its gradients for the texels only the fill lights are heavy-tailed (PT's error hardly moves:
// 0.94-0.96x, StabilityDeep.OxalisPtBaseline). ReSTIR's reused fill samples take it to 0.30x.
TEST(Stability, OnOxalisRestirConverges) {
  double initial = 0;
  const double restir = finalError("oxalis", invr::v1::METHOD_RESTIR, &initial);
  std::printf("oxalis, 150 steps: parameter RMSE %.4f -> restir %.4f\n", initial, restir);
  ::testing::Test::RecordProperty("restir_ratio", std::to_string(restir / initial));
  EXPECT_LT(restir, 0.4 * initial) << "ReSTIR stopped converging on oxalis";
}

// The baselines' runs (the deep suite's: they assert nothing and cost as much as the tests above),
// recorded as figures of the run (`pt_ratio` in the test's XML).
void ptBaseline(const char* scene) {
  double initial = 0;
  const double pt = finalError(scene, invr::v1::METHOD_PT, &initial);
  std::printf("%s, 150 steps: parameter RMSE %.4f -> pt %.4f (%.2fx)\n", scene, initial, pt, pt / initial);
  ::testing::Test::RecordProperty("pt_ratio", std::to_string(pt / initial));
}
TEST(StabilityDeep, AjarPtBaseline) { ptBaseline("ajar"); }
TEST(StabilityDeep, OxalisPtBaseline) { ptBaseline("oxalis"); }

}  // namespace
}  // namespace invr
