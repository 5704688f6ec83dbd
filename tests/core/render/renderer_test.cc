#include "core/render/renderer.h"
#include "core/render/path_tracer.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cstdio>
#include <cstring>

#include "core/diff/diff_scenes.h"
#include "core/error.h"
#include "core/scene/zoo.h"
#include "test_util.h"

namespace invr {
namespace {

// White furnace: an albedo-1 diffuse convex object inside a constant environment of radiance 1
// reflects exactly 1 everywhere (every cosine-weighted direction above a convex surface escapes).
constexpr const char* kFurnace = R"({
  "materials": [{"name": "white", "diffuse": {"albedo": {"value": 1}}}],
  "shapes": [{"name": "box", "material": "white", "box": {},
              "transform": {"rotate_xyz_degrees": {"x": 20, "y": 35}}}],
  "lights": [{"name": "sky", "constant_environment": {"radiance": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "fov_y_degrees": 45}],
  "film": {"width": 48, "height": 48}
})";

TEST(Renderer, WhiteFurnace) {
  auto scene = test::sceneFromJson(kFurnace);
  struct Variant { LightEstimator est; int depth; SamplerKind sampler = SamplerKind::Independent; };
  for (auto v : {Variant{LightEstimator::NeeMis, 1}, Variant{LightEstimator::NeeMis, 6}, Variant{LightEstimator::Ris, 1},
                 Variant{LightEstimator::Ris, 6}, Variant{LightEstimator::NeeMis, 6, SamplerKind::Sobol},
                 Variant{LightEstimator::Ris, 6, SamplerKind::Sobol}}) {
    RenderOptions opt;
    opt.estimator = v.est;
    opt.sampler = v.sampler;
    opt.maxDepth = v.depth;
    opt.spp = 8;
    RenderResult r = renderView(*scene, 0, opt);
    // Pixels are independent estimates (distinct RNG keys), so their spread gives the SE.
    test::MeanSE m;
    for (int y = 0; y < r.image.height(); ++y)
      for (int x = 0; x < r.image.width(); ++x) m.add(r.image.at(x, y, 1));
    m.mean *= test::mutation();
    EXPECT_NEAR(m.mean, 1.0, test::kSigmas * m.se() + 1e-5) << "depth " << v.depth << ", " << samplerKindName(v.sampler);
    test::expectPower("furnace, depth " + std::to_string(v.depth) + ", " + samplerKindName(v.sampler), m.se(), 1.0);
    EXPECT_EQ(r.nonFiniteSamples, 0u);
  }
}

TEST(Renderer, BitIdenticalForAnyThreadCount) {
  auto spec = zooScene("cornell");
  spec.mutable_film()->set_width(64);
  spec.mutable_film()->set_height(48);
  auto scene = buildScene(spec);
  for (auto [est, sampler] : {std::pair{LightEstimator::NeeMis, SamplerKind::Independent}, std::pair{LightEstimator::Ris, SamplerKind::Independent},
                              std::pair{LightEstimator::NeeMis, SamplerKind::Sobol}, std::pair{LightEstimator::Ris, SamplerKind::Sobol}}) {
    RenderOptions opt;
    opt.spp = 4;
    opt.maxDepth = 4;
    opt.estimator = est;
    opt.sampler = sampler;
    std::vector<Image> images;
    for (int threads : {1, 2, 5}) {
      tbb::task_arena arena(threads);
      arena.execute([&] { images.push_back(renderView(*scene, 0, opt).image); });
    }
    for (size_t i = 1; i < images.size(); ++i)
      EXPECT_EQ(0, std::memcmp(images[0].data().data(), images[i].data().data(), images[0].data().size() * sizeof(float)));
  }
}

// A crop window renders exactly the whole film's pixels inside it (samples are keyed by the pixel)
// and leaves the rest black; a window reaching past the film is clipped to it.
TEST(Renderer, CropWindowRendersThoseVeryPixels) {
  auto spec = zooScene("cornell");
  spec.mutable_film()->set_width(40);
  spec.mutable_film()->set_height(30);
  auto scene = buildScene(spec);
  RenderOptions opt;
  opt.spp = 2;
  opt.maxDepth = 3;
  const Image whole = renderView(*scene, 0, opt).image;
  opt.window = {7, 5, 60, 19};
  const Image crop = renderView(*scene, 0, opt).image;
  int inside = 0;
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) {
      const bool in = x >= 7 && y >= 5 && y < 19;
      const Rgb a = crop.rgb(x, y), b = in ? whole.rgb(x, y) : Rgb(0.f, 0.f, 0.f);
      ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z) << "pixel " << x << "," << y;
      inside += in && (b.x + b.y + b.z) > 0.f;
    }
  EXPECT_GT(inside, 100);  // the window saw the scene, not black
}

// The renderer queues a range's camera rays and traces them as packets (core/geometry/ray_queue.h)
// before walking them: each pixel is the one-by-one render of its samples (the same sampler, the
// same film draw, the same sum), to the bit, unless a camera ray grazed an edge and its packet
// rounded it differently. 5 spp: a pixel's samples straddle the queue's batches of 64.
TEST(Renderer, QueuedCameraRaysRenderWhatOneByOneWould) {
  auto spec = zooScene("cornell");
  spec.mutable_film()->set_width(40);
  spec.mutable_film()->set_height(30);
  auto scene = buildScene(spec);
  const Camera& cam = scene->cameras[0];
  for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol}) {
    RenderOptions opt;
    opt.spp = 5;
    opt.maxDepth = 3;
    opt.sampler = kind;
    opt.seed = 3;
    const Image im = renderView(*scene, 0, opt).image;
    int differing = 0, lit = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) {
        const uint64_t hash = RngKey{opt.seed, 0, 0, uint64_t(y * 40 + x), 0}.pixelHash();
        double acc[3] = {0, 0, 0};
        for (int s = 0; s < opt.spp; ++s) {
          Sampler sampler = Sampler::forSample(kind, hash, uint64_t(s));
          const Vec2 film = sampler.next2D();
          const Rgb L = pathRadiance(*scene, cam.eye, cam.direction(float(x) + film.x, float(y) + film.y, 40, 30), sampler, opt);
          acc[0] += L.x, acc[1] += L.y, acc[2] += L.z;
        }
        const Rgb alone(float(acc[0] / opt.spp), float(acc[1] / opt.spp), float(acc[2] / opt.spp)), got = im.rgb(x, y);
        differing += !(got.x == alone.x && got.y == alone.y && got.z == alone.z);
        lit += got.x + got.y + got.z > 0.f;
      }
    EXPECT_LE(differing, 1) << "sampler " << int(kind);
    EXPECT_GT(lit, 600);
  }
}

// The seed selects the noise, not the image it estimates: renders with seeds 0-31 and 32-63 agree
// region by region within their standard errors (from each pixel's own spread), and two seeds'
// deviations from that mean are uncorrelated (independent noise, not the same noise shifted).
TEST(Renderer, SeedChangesNoiseNotExpectation) {
  auto scene = test::sceneFromJson(test::kDiffScene);
  const int W = scene->width, H = scene->height;
  test::PixelStats a(W, H), b(W, H);
  std::vector<Image> first;
  for (uint64_t seed = 0; seed < 64; ++seed) {
    RenderOptions o;
    o.spp = 8;
    o.seed = seed;
    Image im = renderView(*scene, 0, o).image;
    (seed < 32 ? a : b).add(im);
    if (seed < 2) first.push_back(std::move(im));
  }
  test::RegionComparison c = test::compareRegions(a, b, 4);
  std::printf("%zu regions: max |z| %.2f, mean z^2 %.2f\n", c.z.size(), c.maxAbsZ(), c.meanZ2());
  ASSERT_GE(c.z.size(), 40u);
  EXPECT_LT(c.maxAbsZ(), 4.5);
  EXPECT_GT(c.meanZ2(), 0.4);
  EXPECT_LT(c.meanZ2(), 1.8);
  test::expectPower("seeds 0-31 against 32-63, three regions in four", test::upperQuartile(c.relativeSe), 1.0);
  // Correlation of the two seeds' deviations over the pixels with any noise: about N(0, 1/n).
  double sxy = 0, sxx = 0, syy = 0;
  size_t n = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const test::MeanSE& m = a.pixel[size_t(y * W + x)];
      if (!(m.se() > 0)) continue;
      double dx = luminance(first[0].rgb(x, y)) - m.mean, dy = luminance(first[1].rgb(x, y)) - m.mean;
      sxy += dx * dy;
      sxx += dx * dx;
      syy += dy * dy;
      ++n;
    }
  ASSERT_GT(n, 200u);
  double corr = sxy / std::sqrt(sxx * syy);
  std::printf("correlation of seed 0 and seed 1 noise over %zu pixels: %.3f\n", n, corr);
  // Both deviations share the 1/32 of the mean they contributed: a bias of about +1/32 in the
  // correlation, well inside the 4/sqrt(n) bound that identical noise (correlation 1) breaks.
  EXPECT_LT(std::abs(corr), test::kSigmas / std::sqrt(double(n)) + 1.0 / 32);
}

// The sobol sampler estimates the same image: 32 seeds of it (independent scrambles, so their
// spread is its real error) agree region by region with 32 seeds of independent samples, with
// two bounces (every domain of a path in use) and with RIS's candidates; and it is less noisy.
TEST(Renderer, SobolSamplesEstimateTheSameImageWithLessNoise) {
  auto scene = test::sceneFromJson(test::kDiffScene);
  const int W = scene->width, H = scene->height;
  for (LightEstimator est : {LightEstimator::NeeMis, LightEstimator::Ris}) {
    test::PixelStats ind(W, H), sob(W, H);
    for (uint64_t seed = 0; seed < 32; ++seed) {
      RenderOptions o;
      o.spp = 16;
      o.seed = seed;
      o.maxDepth = 3;
      o.estimator = est;
      ind.add(renderView(*scene, 0, o).image);
      o.sampler = SamplerKind::Sobol;
      o.seed = 1000 + seed;
      sob.add(renderView(*scene, 0, o).image);
    }
    test::RegionComparison c = test::compareRegions(ind, sob, 4);
    double varInd = 0, varSob = 0;
    for (size_t p = 0; p < ind.pixel.size(); ++p) {
      varInd += ind.pixel[p].se() * ind.pixel[p].se();
      varSob += sob.pixel[p].se() * sob.pixel[p].se();
    }
    std::printf("%s: %zu regions, max |z| %.2f, mean z^2 %.2f; pixel variance independent / sobol %.2f\n",
                est == LightEstimator::Ris ? "ris" : "nee", c.z.size(), c.maxAbsZ(), c.meanZ2(), varInd / varSob);
    ASSERT_GE(c.z.size(), 40u);
    EXPECT_LT(c.maxAbsZ(), 4.5);
    EXPECT_LT(c.meanZ2(), 1.8);
    test::expectPower(std::string(est == LightEstimator::Ris ? "ris" : "nee") + ": sobol against independent, three regions in four",
                      test::upperQuartile(c.relativeSe), 1.0);
    EXPECT_GT(varInd / varSob, 1.2);  // 16 stratified samples: measured 4.1 (nee) and 1.5 (ris), printed above
  }
}

TEST(Renderer, AovsDescribeTheFirstHit) {
  auto scene = test::sceneFromJson(kFurnace);
  Aovs a = renderAovs(*scene, 0);
  // Centre pixel sees the box (albedo 1, unit normal, depth below the eye distance of 4);
  // a corner pixel sees only the environment.
  int c = scene->width / 2;
  EXPECT_FLOAT_EQ(a.albedo.at(c, c, 0), 1.f);
  EXPECT_NEAR(length(a.normal.rgb(c, c)), 1.f, 1e-5f);
  EXPECT_GT(a.depth.at(c, c, 0), 1.5f);
  EXPECT_LT(a.depth.at(c, c, 0), 4.f);
  EXPECT_EQ(a.depth.at(0, 0, 0), 0.f);
}

TEST(Renderer, RejectsBadArguments) {
  auto scene = test::sceneFromJson(kFurnace);
  RenderOptions opt;
  EXPECT_THROW(renderView(*scene, 3, opt), InputError);
  opt.spp = -1;
  EXPECT_THROW(renderView(*scene, 0, opt), InputError);
}

TEST(Renderer, RenderSettingsDefaultsAndErrors) {
  invr::v1::RenderSettings r;
  RenderOptions o = renderOptionsFrom(r);
  EXPECT_EQ(o.spp, 16);
  EXPECT_EQ(o.maxDepth, 1);
  EXPECT_EQ(o.estimator, LightEstimator::NeeMis);
  r.set_spp(-1);
  EXPECT_THROW(renderOptionsFrom(r), InputError);
}

}  // namespace
}  // namespace invr
