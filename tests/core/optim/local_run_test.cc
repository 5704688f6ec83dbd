#include "core/optim/local_run.h"

#include <gtest/gtest.h>

#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/scene/zoo.h"

namespace invr {
namespace {

invr::v1::JobSpec smallCornell() {
  auto job = zooJob("cornell");
  auto* scene = job.mutable_scene();
  *scene = zooScene("cornell");
  scene->mutable_film()->set_width(48);
  scene->mutable_film()->set_height(48);
  job.mutable_optimization()->set_target_spp(64);
  job.mutable_optimization()->set_steps(60);
  return job;
}

TEST(LocalRun, RecoversCornellWallAlbedos) {
  for (auto method : {invr::v1::METHOD_PT, invr::v1::METHOD_RESTIR}) {
    auto job = smallCornell();
    job.mutable_optimization()->set_method(method);
    Problem p = buildProblem(job);
    double before = parameterError(p, p.initial);
    int reports = 0;
    auto result = runLocally(p, [&](const StepReport&) { ++reports; });
    EXPECT_EQ(reports, 60);
    // 60 Adam steps at lr 0.02 from 0.5 everywhere: the error must fall by far more than noise.
    EXPECT_LT(result.history.back().parameterError, 0.25 * before) << invr::v1::GradientMethod_Name(method);
    EXPECT_LT(result.history.back().loss, result.history.front().loss);
  }
}

TEST(LocalRun, SameJobSameNumbers) {
  auto job = smallCornell();
  job.mutable_optimization()->set_steps(5);
  Problem a = buildProblem(job), b = buildProblem(job);
  EXPECT_EQ(runLocally(a).theta, runLocally(b).theta);
}

TEST(LocalRun, DivergenceIsReportedNotReturned) {
  auto job = zooJob("tree");
  auto* scene = job.mutable_scene();
  *scene = zooScene("tree");
  scene->mutable_film()->set_width(24);
  scene->mutable_film()->set_height(18);
  auto* o = job.mutable_optimization();
  o->set_target_spp(4);
  o->set_steps(5);
  o->clear_parameters();
  auto* light = o->add_parameters();
  light->set_name("lights/small/intensity");
  light->set_initial(150);
  light->set_learning_rate(3e38);  // intensity is unbounded above: overflows
  Problem p = buildProblem(job);
  try {
    runLocally(p);
    FAIL() << "expected divergence";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter 'lights/small/intensity' reached"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("diverged"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace invr
