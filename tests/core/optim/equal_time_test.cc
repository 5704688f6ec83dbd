// The equal-time loop: runs until its budget is spent, counts only its own work, records the
// start (step 0) and the image error at the start, at checkpoints and at the end.
#include <gtest/gtest.h>

#include <cmath>

#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/optim/equal_time.h"

namespace invr {
namespace {

TEST(EqualTime, SpendsItsBudgetAndMeasuresAtCheckpoints) {
  auto job = zooJob("cornell");
  job.mutable_optimization()->set_target_spp(4);
  Problem p = buildProblem(job);
  auto targets = renderTargets(p);
  ImageErrorMeter meter(p, 1, 1);
  EqualTimeOptions budget;
  budget.seconds = 0.6;
  budget.imageErrorCheckpoints = 3;
  GradientOptions o = p.gradient;
  o.method = GradientMethod::Pt;
  int seen = 0;
  EqualTimeRun run = runEqualTime(p, targets, o, budget, &meter, [&](const EqualTimePoint&) { ++seen; });
  ASSERT_GE(run.history.size(), 3u);
  EXPECT_EQ(seen, int(run.history.size()));
  EXPECT_EQ(run.history.front().step, 0);
  EXPECT_TRUE(std::isfinite(run.history.front().imageError));
  EXPECT_TRUE(std::isfinite(run.history.back().imageError));
  EXPECT_GE(run.history.back().seconds, budget.seconds);
  int measured = 0;
  for (size_t i = 1; i < run.history.size(); ++i) {
    EXPECT_EQ(run.history[i].step, int(i));
    EXPECT_GE(run.history[i].seconds, run.history[i - 1].seconds);
    measured += std::isfinite(run.history[i].imageError) ? 1 : 0;
  }
  EXPECT_GE(measured, 1);
  EXPECT_LE(measured, budget.imageErrorCheckpoints + 1);
  // Cornell's albedos are easy: the error falls in well under a second of steps.
  EXPECT_LT(run.history.back().parameterError, run.history.front().parameterError);
  EXPECT_DOUBLE_EQ(run.history.back().parameterError, parameterError(p, run.theta));
}

TEST(EqualTime, ADivergingMethodStopsWithTheReasonAndItsLastGoodParameters) {
  // Light intensities have no physical upper bound, so an absurd rate walks them past 1e30.
  auto job = zooJob("tree");
  job.mutable_optimization()->set_target_spp(2);
  job.mutable_optimization()->clear_parameters();
  auto* light = job.mutable_optimization()->add_parameters();
  light->set_name("lights/small/intensity");
  light->set_initial(150);
  light->set_learning_rate(1e38);
  Problem p = buildProblem(job);
  auto targets = renderTargets(p);
  EqualTimeOptions budget;
  budget.seconds = 20;  // a run that failed to stop would spend it and record many steps
  EqualTimeRun run = runEqualTime(p, targets, p.gradient, budget, nullptr);
  ASSERT_FALSE(run.failure.empty());
  EXPECT_NE(run.failure.find("diverged"), std::string::npos) << run.failure;
  for (float v : run.theta) EXPECT_TRUE(std::isfinite(v) && std::abs(v) <= kDivergenceLimit);
  // A rate of 1e38 leaves the physical range on the first step: only the start is recorded.
  EXPECT_EQ(run.history.size(), 1u);
  EXPECT_EQ(run.history.back().step, 0);
}

// The last quarter of a 4 s budget is [3, 4] s: steps at 3 and 4 s (errors 3 and 4) give
// sqrt((9 + 16) / 2); earlier steps and the step-0 point do not count.
TEST(EqualTime, TailErrorIsTheRmsOverTheLastQuarterOfTheBudget) {
  auto point = [](int step, double seconds, double error) {
    EqualTimePoint p;
    p.step = step;
    p.seconds = seconds;
    p.parameterError = error;
    return p;
  };
  const std::vector<EqualTimePoint> run{point(0, 0, 10), point(1, 1, 7), point(2, 2.9, 5), point(3, 3, 3), point(4, 4, 4)};
  EXPECT_DOUBLE_EQ(tailParameterError(run, 4.0), std::sqrt(12.5));
  // No step in the last quarter (one long step): the final value.
  EXPECT_DOUBLE_EQ(tailParameterError({point(0, 0, 10), point(1, 2, 6)}, 4.0), 6.0);
  // Jobs without ground truth report -1, never an error of 1.
  EXPECT_DOUBLE_EQ(tailParameterError({point(0, 0, -1), point(1, 3.5, -1)}, 4.0), -1.0);
}

// A budget in steps (Wang et al.'s fixed iteration counts): exactly that many steps whatever the
// seconds, ReSTIR's burn-in not counted, and the tail over the last quarter of the steps.
TEST(EqualTime, ABudgetInStepsTakesThatManySteps) {
  auto job = zooJob("cornell");
  job.mutable_optimization()->set_target_spp(4);
  Problem p = buildProblem(job);
  p.burnIn = 2;
  auto targets = renderTargets(p);
  EqualTimeOptions budget;
  budget.seconds = 1e-9;  // ignored
  budget.steps = 4;
  GradientOptions o = p.gradient;
  o.method = GradientMethod::Restir;
  EqualTimeRun run = runEqualTime(p, targets, o, budget, nullptr);
  ASSERT_EQ(run.history.size(), 5u);
  EXPECT_EQ(run.history.back().step, 4);
  // The last quarter of 4 steps is steps 3 and 4 (errors 3 and 4): sqrt((9 + 16) / 2).
  std::vector<EqualTimePoint> made(5);
  const double errors[] = {10, 7, 5, 3, 4};
  for (int i = 0; i < 5; ++i) made[size_t(i)].step = i, made[size_t(i)].parameterError = errors[i];
  EXPECT_DOUBLE_EQ(tailParameterError(made, budget), std::sqrt(12.5));
  budget.steps = 40;  // no step in its last quarter: the final value
  EXPECT_DOUBLE_EQ(tailParameterError(made, budget), 4.0);
}

TEST(EqualTime, RejectsANonPositiveBudget) {
  auto job = zooJob("cornell");
  job.mutable_optimization()->set_target_spp(1);
  Problem p = buildProblem(job);
  EqualTimeOptions budget;
  budget.seconds = 0;
  EXPECT_THROW(runEqualTime(p, {}, p.gradient, budget, nullptr), InputError);
}

}  // namespace
}  // namespace invr
