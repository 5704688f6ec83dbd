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

// A parameter at 0 changes which light samples ReSTIR's reused reservoirs could have produced:
// the default bounds keep albedos and intensities above 0, and an explicit 0 with ReSTIR is refused
// (other methods accept it). The scene's own values start inside the bounds.
TEST(Problem, RestirKeepsParametersOffZero) {
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "lower": 0}]})"),
                  "optimization.parameters[0].lower: must be above 0 with method METHOD_RESTIR");
  EXPECT_MENTIONS(errorOf(R"({"method": "METHOD_RESTIR", "parameters": [{"name": "materials/red/albedo"}, {"name": "lights/ceiling_light/intensity", "lower": 0}]})"),
                  "optimization.parameters[1].lower");
  EXPECT_EQ(errorOf(R"({"method": "METHOD_RIS", "parameters": [{"name": "materials/red/albedo", "lower": 0}]})"), "");
  auto job = parseJobJson(R"({"zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo"}]}})", "job.json");
  Problem p = buildProblem(job);
  EXPECT_EQ(p.params.slots()[0].lower, kPositiveFloor);
  for (float v : p.initial) EXPECT_GE(v, kPositiveFloor);
}

// Targets, gradients and final renders share one light transport: a job whose render block asks
// for another depth is refused, naming both fields; the transport follows optimization.max_depth.
TEST(Problem, OneLightTransportForTargetsGradientsAndRenders) {
  auto with = [](const std::string& render, const std::string& optimization) {
    try {
      auto job = parseJobJson(R"({"zoo": "cornell", "render": )" + render + R"(, "optimization": )" + optimization + "}", "job.json");
      buildProblem(job);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string albedo = R"("parameters": [{"name": "materials/red/albedo"}])";
  std::string err = with(R"({"max_depth": 3})", "{" + albedo + "}");
  EXPECT_MENTIONS(err, "render.max_depth (3)");
  EXPECT_MENTIONS(err, "optimization.max_depth (1");
  EXPECT_MENTIONS(with(R"({"max_depth": 1})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "render.max_depth (1)");
  EXPECT_EQ(with(R"({"max_depth": 4, "spp": 8})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "");
  EXPECT_EQ(with(R"({"spp": 8})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "");
  auto job = parseJobJson(R"({"zoo": "cornell", "optimization": {"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}}", "job.json");
  Problem p = buildProblem(job);
  for (Stream s : {Stream::Target, Stream::FinalRender, Stream::ImageError}) {
    RenderOptions ro = transportRenderOptions(p, 16, s);
    EXPECT_EQ(ro.maxDepth, 4);
    EXPECT_EQ(ro.estimator, LightEstimator::NeeMis);
  }
  EXPECT_EQ(targetRenderOptions(p).maxDepth, 4);
  EXPECT_NE(transportRenderOptions(p, 16, Stream::Target).seed, transportRenderOptions(p, 16, Stream::FinalRender).seed);
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
