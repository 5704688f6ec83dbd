// Inverse problems from job JSON: every mistake names the field; mini-batches are deterministic.
#include "core/diff/problem.h"

#include <gtest/gtest.h>

#include "core/diff/zoo_jobs.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/scene/zoo.h"

namespace invr {
namespace {

std::string errorOf(const std::string& optimizationJson) {
  try {
    auto job = parseJobJson(R"({"zoo": "cornell", "optimization": )" + optimizationJson + "}", "job.json");
    buildProblem(job);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_MENTIONS(err, part) EXPECT_NE((err).find(part), std::string::npos) << "error was: " << (err)

TEST(Problem, JobMistakesNameTheField) {
  EXPECT_MENTIONS(errorOf(R"({})"), "optimization.parameters: list at least one");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/wood/albedo"}]})"),
                  "optimization.parameters[0].name: parameter 'materials/wood/albedo': no material named 'wood'");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": "NaN"}]})"),
                  "optimization.parameters[0].initial: must be a finite number");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": 1.5}]})"),
                  "optimization.parameters[0].initial: outside the bounds");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "lower": 0.9, "upper": 0.1}]})"),
                  "bounds are inverted");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "learning_rate": -1}]})"), "learning rate");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "steps": -5})"), "optimization.steps");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "loss": "l7"})"), "optimization.loss");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "optimizer": "lbfgs"})"), "optimization.optimizer");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "learning_rate_half_life": -3})"),
                  "optimization.learning_rate_half_life: must be a finite number of steps >= 0");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "learning_rate_half_life": "Infinity"})"),
                  "optimization.learning_rate_half_life");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "views_per_step": 3})"),
                  "optimization.views_per_step: must be in 1..1");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "restir": {"radius_pixels": -2}})"),
                  "optimization.restir.radius_pixels");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": 0.3}]})"), "");
}

TEST(Problem, InitialValuesAndBatchesAreDeterministic) {
  auto job = zooJob("backlit");
  job.mutable_optimization()->set_target_spp(4);
  Problem p = buildProblem(job);
  for (float v : p.initial) EXPECT_FLOAT_EQ(v, 0.5f);
  EXPECT_GT(parameterError(p, p.initial), 0.05);
  EXPECT_EQ(parameterError(p, p.truth), 0.0);
  auto a = viewsForStep(p, 7), b = viewsForStep(p, 7), c = viewsForStep(p, 8);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a.size(), 4u);
  EXPECT_NE(a, c);
  for (int v : a) EXPECT_LT(v, 16);
}

TEST(Problem, EveryZooSceneHasAValidJob) {
  for (const auto& e : zooEntries()) {
    auto job = zooJob(e.name);
    Problem p = buildProblem(job);
    EXPECT_GT(p.params.size(), 0u) << e.name;
    EXPECT_NE(p.initial, p.truth) << e.name;
  }
}

}  // namespace
}  // namespace invr
