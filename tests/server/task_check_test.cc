// A worker's result is checked against the task it answers before the server uses any of it.
#include "server/task_check.h"

#include <gtest/gtest.h>

#include <cmath>

namespace invr::server {
namespace {

namespace v1 = invr::v1;

v1::Task gradientTask(bool renderOnly = false) {
  v1::Task t;
  t.set_task_id(7);
  t.set_job_id("job-000001");
  t.set_kind(v1::Task::GRADIENT);
  t.set_shard(1);
  t.add_views(2);
  t.add_views(3);
  t.set_render_only(renderOnly);
  return t;
}

v1::TaskResult answer(const v1::Task& t, int gradientValues) {
  v1::TaskResult r;
  r.set_task_id(t.task_id());
  r.set_job_id(t.job_id());
  r.set_shard(t.shard());
  for (int k = 0; k < gradientValues; ++k) r.add_gradient(0.5);
  r.mutable_stats()->set_loss(1.0);
  return r;
}

const ResultShape kShape{12, 8, 6};

TEST(TaskCheck, AWellFormedGradientPasses) {
  v1::Task t = gradientTask();
  EXPECT_EQ(checkTaskResult(t, answer(t, 12), kShape), "");
}

TEST(TaskCheck, TheWrongGradientLengthIsNamed) {
  v1::Task t = gradientTask();
  EXPECT_EQ(checkTaskResult(t, answer(t, 13), kShape), "gradient has 13 values, the job has 12 parameters");
  EXPECT_EQ(checkTaskResult(t, answer(t, 0), kShape), "gradient has 0 values, the job has 12 parameters");
}

TEST(TaskCheck, RenderOnlyStepsMayOmitTheGradientButNotHaveAWrongOne) {
  v1::Task t = gradientTask(true);
  EXPECT_EQ(checkTaskResult(t, answer(t, 0), kShape), "");
  EXPECT_EQ(checkTaskResult(t, answer(t, 12), kShape), "");
  EXPECT_NE(checkTaskResult(t, answer(t, 5), kShape), "");
}

TEST(TaskCheck, IdentityMustMatchTheTask) {
  v1::Task t = gradientTask();
  v1::TaskResult r = answer(t, 12);
  r.set_shard(0);
  EXPECT_NE(checkTaskResult(t, r, kShape).find("shard 0"), std::string::npos);
  r = answer(t, 12);
  r.set_job_id("job-000002");
  EXPECT_NE(checkTaskResult(t, r, kShape).find("job-000002"), std::string::npos);
  r = answer(t, 12);
  r.set_task_id(8);
  EXPECT_NE(checkTaskResult(t, r, kShape), "");
}

TEST(TaskCheck, NegativeOrNonFiniteTimingsAreMalformed) {
  v1::Task t = gradientTask();
  v1::TaskResult r = answer(t, 12);
  r.mutable_stats()->set_seconds_primal(-1);
  EXPECT_EQ(checkTaskResult(t, r, kShape), "statistic 'seconds_primal' is negative or not finite");
  r = answer(t, 12);
  r.set_seconds_session(std::nan(""));
  EXPECT_NE(checkTaskResult(t, r, kShape), "");
  // Inside the statistics' maps too, and the maps stay small.
  r = answer(t, 12);
  (*r.mutable_stats()->mutable_boundary())["primary"].set_seconds(std::nan(""));
  EXPECT_EQ(checkTaskResult(t, r, kShape), "statistic 'seconds' is negative or not finite");
  r = answer(t, 12);
  for (int k = 0; k < 65; ++k) (*r.mutable_stats()->mutable_boundary())["term" + std::to_string(k)].set_samples(1);
  EXPECT_NE(checkTaskResult(t, r, kShape).find("limit 64"), std::string::npos);
  // The loss may be anything: divergence shows there, and the step loop names it.
  r = answer(t, 12);
  r.mutable_stats()->set_loss(std::nan(""));
  EXPECT_EQ(checkTaskResult(t, r, kShape), "");
}

TEST(TaskCheck, FinalRendersMustHaveTheFilmSizeAndTheirPixels) {
  v1::Task t = gradientTask();
  t.set_kind(v1::Task::FINAL_RENDER);
  v1::TaskResult r = answer(t, 0);
  auto addImage = [&](int w, int h, int c, size_t values) {
    v1::FloatImage* im = r.add_renders();
    im->set_width(w);
    im->set_height(h);
    im->set_channels(c);
    for (size_t k = 0; k < values; ++k) im->add_pixels(0.f);
  };
  for (int k = 0; k < 4; ++k) addImage(8, 6, 3, 8 * 6 * 3);  // two views: renders, then targets
  EXPECT_EQ(checkTaskResult(t, r, kShape), "");
  r.mutable_renders(3)->mutable_pixels()->RemoveLast();
  EXPECT_EQ(checkTaskResult(t, r, kShape), "image 3 has 143 values, expected 144");
  r.mutable_renders(3)->add_pixels(0.f);
  r.mutable_renders(1)->set_width(100000);
  EXPECT_EQ(checkTaskResult(t, r, kShape), "image 1 is 100000x6, the film is 8x6");
  r.mutable_renders(1)->set_width(8);
  r.mutable_renders(0)->set_channels(-3);
  EXPECT_NE(checkTaskResult(t, r, kShape), "");
  r.mutable_renders(0)->set_channels(3);
  r.mutable_renders()->RemoveLast();
  EXPECT_EQ(checkTaskResult(t, r, kShape), "3 images for 2 view(s) (expected 4)");
  r = answer(t, 12);
  EXPECT_NE(checkTaskResult(t, r, kShape), "");  // a gradient where images were asked for
}

TEST(TaskCheck, SnapshotsCarryTheirRendersAndTheTargetsOnlyWhenAsked) {
  v1::Task t = gradientTask();
  t.set_kind(v1::Task::SNAPSHOT);
  auto withImages = [&](int n) {
    v1::TaskResult r = answer(t, 0);
    for (int k = 0; k < n; ++k) {
      v1::FloatImage* im = r.add_renders();
      im->set_width(8);
      im->set_height(6);
      im->set_channels(3);
      for (int i = 0; i < 8 * 6 * 3; ++i) im->add_pixels(0.f);
    }
    return r;
  };
  EXPECT_EQ(checkTaskResult(t, withImages(2), kShape), "");
  EXPECT_EQ(checkTaskResult(t, withImages(4), kShape), "4 images for 2 view(s) (expected 2)");  // targets not asked for
  t.set_with_targets(true);
  EXPECT_EQ(checkTaskResult(t, withImages(4), kShape), "");  // renders, then targets
  EXPECT_EQ(checkTaskResult(t, withImages(2), kShape), "");  // a worker without the session has no targets
  EXPECT_EQ(checkTaskResult(t, withImages(3), kShape), "3 images for 2 view(s) (expected 2)");
}

TEST(TaskCheck, ASpecUnknownAnswerCarriesNothingElse) {
  v1::Task t = gradientTask();
  v1::TaskResult r = answer(t, 0);
  r.set_spec_unknown(true);
  EXPECT_EQ(checkTaskResult(t, r, kShape), "");
}

TEST(TaskCheck, AnErrorResultIsWellFormedWhenItsTextIsBounded) {
  v1::Task t = gradientTask();
  v1::TaskResult r = answer(t, 0);
  r.set_error("out of memory");
  EXPECT_EQ(checkTaskResult(t, r, kShape), "");
  r.set_error(std::string(100000, 'x'));
  EXPECT_NE(checkTaskResult(t, r, kShape), "");
}

}  // namespace
}  // namespace invr::server
