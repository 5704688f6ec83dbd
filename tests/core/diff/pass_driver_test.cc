// The pass driver's camera wavefront (a tile's camera rays queued, traced as packets, then shaded
// in order) against the same samples taken one by one, each tracing its own camera ray: the same
// sampler per (pixel, sample), the same film draw, the same pixel averages. A pixel drawn c times
// into a mini-batch takes c x spp samples (3 spp: a pixel's samples straddle the queue's batches
// of 64); a pixel drawn 0 times stays black.
#include "core/diff/pass_driver.h"

#include <gtest/gtest.h>

#include "core/diff/diff_scenes.h"
#include "test_util.h"

namespace invr {
namespace {

TEST(PassDriver, TheCameraWavefrontShadesEachSampleAsItWouldBeAlone) {
  auto scene = test::sceneFromJson(test::kDiffScene);  // 32 x 24: whole and partial tiles
  const int W = scene->width, H = scene->height, spp = 3;
  ParameterRegistry none;
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.maxDepth = 2;
  auto estimator = makePtEstimator({*scene, none, o, 0, spp, nullptr});
  GradientScratchPool scratch(0);
  PixelBatch batch;
  batch.weight.assign(size_t(W * H), 1.f);
  batch.draws.resize(size_t(W * H));
  for (size_t p = 0; p < batch.draws.size(); ++p) batch.draws[p] = uint32_t((p * 7 + p / 5) % 4);
  const Camera& cam = scene->cameras[0];
  for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol}) {
    PassSpec spec;
    spec.stream = 11;
    spec.step = 4;
    spec.spp = spp;
    spec.sampler = kind;
    spec.batch = &batch;
    const PassOutput pass = runPass(*scene, *estimator, spec, scratch);
    EXPECT_EQ(pass.drops.primal, 0u);
    int differing = 0, lit = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const uint64_t pixel = uint64_t(y * W + x);
        const int samples = spp * int(batch.draws[pixel]);
        const uint64_t hash = RngKey{spec.stream, spec.step, 0, pixel, 0}.pixelHash();
        double sum[3] = {0, 0, 0};  // as the driver sums
        for (int s = 0; s < samples; ++s) {
          Sampler sampler = Sampler::forSample(kind, hash, uint64_t(s));
          const Vec2 film = sampler.next2D();
          CameraSampleInput in;
          in.x = x;
          in.y = y;
          in.pixel = pixel;
          in.slot = s % spp;
          in.o = cam.eye;
          in.d = cam.direction(float(x) + film.y, float(y) + film.x, W, H);  // primary null: the walk traces it
          SampleCounters counters;
          const Rgb v = estimator->sample(in, sampler, counters, Rgb(0.f), nullptr, nullptr);
          sum[0] += v.x, sum[1] += v.y, sum[2] += v.z;
        }
        const Rgb alone = samples > 0 ? Rgb(float(sum[0] / samples), float(sum[1] / samples), float(sum[2] / samples)) : Rgb(0.f);
        const Rgb got = pass.image.rgb(x, y);
        if (samples == 0) {
          EXPECT_EQ(got.x + got.y + got.z, 0.f) << "pixel " << x << "," << y << " is not in the batch";
          continue;
        }
        lit += got.x + got.y + got.z > 0.f;
        // Float sums in the same order: equal to the bit, unless a camera ray grazed an edge and
        // its packet rounded it differently (tests/core/geometry/ray_queue_test.cc).
        differing += !(got.x == alone.x && got.y == alone.y && got.z == alone.z);
      }
    EXPECT_LE(differing, 1) << "sampler " << int(kind);
    EXPECT_GT(lit, W * H / 2) << "most batch pixels see something";
  }
}

}  // namespace
}  // namespace invr
