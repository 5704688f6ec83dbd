// The image-error meter renders θ and the truth with the same random numbers, so its error is
// the parameters' effect and not Monte Carlo noise. On cornell every non-emitting surface's
// albedo is a parameter and direct lighting is linear in albedo (RIS's resampling is invariant
// to scaling its target), so θ = c · truth gives I(θ) − I* = (c − 1) I* off the emitter, exactly:
// the error is |c − 1| times a constant. Independent noise would break both properties.
#include <gtest/gtest.h>

#include <cmath>

#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/optim/image_error.h"

namespace invr {
namespace {

Problem cornell() {
  auto job = zooJob("cornell");
  job.mutable_optimization()->set_target_spp(4);
  return buildProblem(job);
}

std::vector<float> scaled(const std::vector<float>& v, float c) {
  std::vector<float> out(v);
  for (float& x : out) x *= c;
  return out;
}

TEST(ImageErrorMeter, ZeroAtTheTruthAndLinearInAnAlbedoScale) {
  Problem p = cornell();
  ImageErrorMeter meter(p, 1, 2);
  EXPECT_EQ(meter.measure(p.truth), 0.0);
  double down = meter.measure(scaled(p.truth, 0.9f));
  double up = meter.measure(scaled(p.truth, 1.1f));
  double far = meter.measure(scaled(p.truth, 0.6f));
  ASSERT_GT(down, 0.0);
  // Per unit of |c - 1| the error is the same constant (float rounding aside) ...
  EXPECT_NEAR(up / down, 1.0, 1e-3);
  EXPECT_NEAR(far / down, 4.0, 4e-3);
  // ... at most 1 (the emitter does not scale, dark pixels count less) and far from 0 (lit walls
  // fill most of the view).
  EXPECT_LT(down / 0.1, 1.0);
  EXPECT_GT(down / 0.1, 0.3);
}

TEST(ImageErrorMeter, ReturnsTheRendersItCompared) {
  Problem p = cornell();
  ImageErrorMeter meter(p, 4, 1);
  std::vector<Image> renders;
  meter.measure(p.initial, &renders);
  ASSERT_EQ(renders.size(), meter.views().size());
  EXPECT_EQ(renders[0].width(), meter.reference()[0].width());
  EXPECT_THROW(ImageErrorMeter(p, 0, 1), InputError);
}

}  // namespace
}  // namespace invr
