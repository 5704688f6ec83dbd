#include "core/render/renderer.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cstring>

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
  struct Variant { LightEstimator est; int depth; };
  for (auto v : {Variant{LightEstimator::NeeMis, 1}, Variant{LightEstimator::NeeMis, 6}, Variant{LightEstimator::Ris, 1},
                 Variant{LightEstimator::Ris, 6}}) {
    RenderOptions opt;
    opt.estimator = v.est;
    opt.maxDepth = v.depth;
    opt.spp = 8;
    RenderResult r = renderView(*scene, 0, opt);
    // Pixels are independent estimates (distinct RNG keys), so their spread gives the SE.
    test::MeanSE m;
    for (int y = 0; y < r.image.height(); ++y)
      for (int x = 0; x < r.image.width(); ++x) m.add(r.image.at(x, y, 1));
    EXPECT_NEAR(m.mean, 1.0, test::kSigmas * m.se() + 1e-5) << "depth " << v.depth;
    EXPECT_EQ(r.nonFiniteSamples, 0u);
  }
}

TEST(Renderer, BitIdenticalForAnyThreadCount) {
  auto spec = zooScene("cornell");
  spec.mutable_film()->set_width(64);
  spec.mutable_film()->set_height(48);
  auto scene = buildScene(spec);
  for (auto est : {LightEstimator::NeeMis, LightEstimator::Ris}) {
    RenderOptions opt;
    opt.spp = 4;
    opt.maxDepth = 4;
    opt.estimator = est;
    std::vector<Image> images;
    for (int threads : {1, 2, 5}) {
      tbb::task_arena arena(threads);
      arena.execute([&] { images.push_back(renderView(*scene, 0, opt).image); });
    }
    for (size_t i = 1; i < images.size(); ++i)
      EXPECT_EQ(0, std::memcmp(images[0].data().data(), images[i].data().data(), images[0].data().size() * sizeof(float)));
  }
}

TEST(Renderer, SeedChangesNoiseNotExpectation) {
  auto scene = test::sceneFromJson(kFurnace);
  RenderOptions a, b;
  b.seed = 1;
  auto ia = renderView(*scene, 0, a).image, ib = renderView(*scene, 0, b).image;
  EXPECT_NE(0, std::memcmp(ia.data().data(), ib.data().data(), ia.data().size() * sizeof(float)));
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

}  // namespace
}  // namespace invr
