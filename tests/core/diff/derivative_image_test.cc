// Derivative images (GradientRequest::derivativeImage, `invr-lab bench derivative-images`): the
// per-pixel derivative of one parameter value from the derivative pass and every boundary term.
//
// 1. Attribution: every sample lands on the pixel whose dL/dI weighs it. With dL/dI = +-1/3 by a
//    random sign per pixel, each pixel's value must be its sign times its value under 1/3 (a term
//    that read one pixel's adjoint and put the sample on another would break it), and the image
//    must sum to the evaluation's own gradient (a term that left the image out would break that).
//    Checked on the zoo's knot (primary and point/spot shadow-border terms), key (area-light
//    shadow borders, edge reservoirs) and oxalis (a light's intensity, interior only).
// 2. Against an independent reference: the forward renderer's central difference per 8x8 block
//    of pixels, common random numbers and light selection frozen, for a point light's intensity.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <random>

#include "core/diff/diff_scenes.h"
#include "core/diff/gradient_engine.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "test_util.h"

namespace invr {
namespace {

// A zoo job on a small film, with only `param` optimised (at the scene's values unless the job has it).
Problem smallZooProblem(const std::string& scene, int w, int h, const std::string& param = "") {
  v1::JobSpec job = zooJob(scene);
  bool has = param.empty();
  for (const auto& ps : job.optimization().parameters()) has = has || ps.name() == param;
  if (!has) {
    job.mutable_optimization()->clear_parameters();
    job.mutable_optimization()->add_parameters()->set_name(param);
  }
  v1::Scene s = jobSceneSpec(job);
  s.mutable_film()->set_width(w);
  s.mutable_film()->set_height(h);
  *job.mutable_scene() = s;
  return buildProblem(job);
}

struct ImageRun {
  std::vector<double> image;
  double gradient = 0;
};

ImageRun runImage(Problem& p, GradientMethod method, uint32_t index, const Image* weights) {
  GradientOptions o = p.gradient;
  o.method = method;
  o.sppPrimal = o.sppGradient = 2;
  GradientEngine engine(*p.scene, p.params, {}, o);
  EngineSession session;
  GradientRequest r;
  r.views = {0};
  r.seed = 17;
  r.allSessionViews = true;
  for (uint64_t b = 0; method == GradientMethod::Restir && b < 2; ++b) {  // reservoirs to reuse
    GradientRequest rb = r;
    rb.renderOnly = true;
    rb.step = b;
    engine.evaluate(rb, session);
  }
  PixelDerivativeSink sink;
  sink.index = index;
  r.step = 2;
  r.derivativeImage = &sink;
  r.derivativeWeights = weights;
  const GradientResult g = engine.evaluate(r, session);
  return {sink.image, g.gradient[index]};
}

void expectAttributed(const std::string& scene, const std::string& param, size_t component, GradientMethod method) {
  SCOPED_TRACE(scene + " " + param + " " + gradientMethodName(method));
  Problem p = smallZooProblem(scene, 64, 48, param);
  const ParameterSlot* slot = p.params.find(param);
  ASSERT_NE(slot, nullptr);
  const uint32_t index = slot->offset + uint32_t(component);
  const ImageRun plain = runImage(p, method, index, nullptr);
  Image signs(p.scene->width, p.scene->height, 3);
  std::mt19937 rng(5);
  std::vector<double> sign(plain.image.size());
  for (int y = 0; y < signs.height(); ++y)
    for (int x = 0; x < signs.width(); ++x) {
      sign[size_t(y) * size_t(signs.width()) + size_t(x)] = rng() % 2 ? 1.0 : -1.0;
      signs.setRgb(x, y, Rgb(float(sign[size_t(y) * size_t(signs.width()) + size_t(x)] / 3.0)));
    }
  const ImageRun signed_ = runImage(p, method, index, &signs);
  double sum = 0, sumAbs = 0, worst = 0;
  size_t nonzero = 0;
  for (size_t i = 0; i < plain.image.size(); ++i) {
    sum += plain.image[i];
    sumAbs += std::abs(plain.image[i]);
    nonzero += plain.image[i] != 0.0;
  }
  ASSERT_GT(nonzero, plain.image.size() / 50) << "the derivative image is (almost) empty";
  for (size_t i = 0; i < plain.image.size(); ++i) worst = std::max(worst, std::abs(signed_.image[i] - sign[i] * plain.image[i]));
  // Float rounding only: a sample's entries are floats summed in double.
  EXPECT_LE(worst, 1e-5 * sumAbs / double(nonzero)) << "a sample was put on another pixel than the one whose dL/dI weighed it";
  EXPECT_NEAR(sum, plain.gradient, 1e-6 * sumAbs) << "the image and the gradient hold different samples";
}

TEST(DerivativeImage, EachSampleSitsOnThePixelWhoseAdjointWeighsIt) {
  expectAttributed("knot", "shapes/knot/translation", 0, GradientMethod::Ris);  // primary, delta-light shadow borders
  expectAttributed("key", "groups/key/rotation", 1, GradientMethod::Restir);     // primary, area-light shadow borders (edge reservoirs)
  expectAttributed("oxalis", "lights/spot_left/intensity", 0, GradientMethod::Pt);
}

// Tiles and boundary chunks are reduced in order: one thread or four give the same image, bit for bit.
TEST(DerivativeImage, SameImageForAnyThreadCount) {
  Problem p = smallZooProblem("key", 64, 48);
  const uint32_t index = p.params.find("groups/key/rotation")->offset + 1;
  std::vector<double> images[2];
  const int threads[2] = {1, 4};
  for (int k = 0; k < 2; ++k) {
    tbb::task_arena arena(threads[k]);
    arena.execute([&] { images[k] = runImage(p, GradientMethod::Restir, index, nullptr).image; });
  }
  EXPECT_EQ(images[0], images[1]);
}

TEST(DerivativeImage, RefusesWhatItCannotMean) {
  Problem p = smallZooProblem("knot", 32, 24);
  GradientEngine engine(*p.scene, p.params, {}, p.gradient);
  EngineSession session;
  PixelDerivativeSink sink;
  GradientRequest r;
  r.views = {0};
  r.derivativeImage = &sink;
  sink.index = uint32_t(p.params.size());
  EXPECT_THROW(engine.evaluate(r, session), InputError);  // past the parameters
  sink.index = 0;
  Image wrong(8, 8, 3);
  r.derivativeWeights = &wrong;
  EXPECT_THROW(engine.evaluate(r, session), InputError);  // weights of another size
}

// The bulb's red intensity: its derivative image is the bulb's share of each pixel's red divided by
// the intensity, a third of it in the channel mean. Blocks of 8x8 pixels (12 of them) of the mean
// of 48 images at 4 spp against the renderer's central difference at 1024 spp.
TEST(DerivativeImage, MatchesFiniteDifferencesOfTheRender) {
  auto scene = test::sceneFromJson(test::kDiffScene);
  ParameterRegistry reg;
  reg.add(*scene, "lights/bulb/intensity");
  const std::vector<float> theta = reg.read(*scene);
  const int W = scene->width, H = scene->height, B = 8, bx = W / B, by = H / B;
  // Reference: light selection frozen at theta, the same seed on both sides.
  const float h = 0.05f * theta[0];
  auto render = [&](float delta) {
    std::vector<float> t = theta;
    t[0] += delta;
    reg.write(t, *scene, /*refreshSampling=*/false);
    RenderOptions o;
    o.spp = 1024;
    o.seed = 3;
    return renderView(*scene, 0, o).image;
  };
  const Image plus = render(h), minus = render(-h);
  reg.write(theta, *scene);
  std::vector<double> fd(size_t(bx * by), 0.0);
  for (int y = 0; y < by * B; ++y)
    for (int x = 0; x < bx * B; ++x) {
      const Rgb d = plus.rgb(x, y) - minus.rgb(x, y);
      fd[size_t((y / B) * bx + x / B)] += double(d.x + d.y + d.z) / 3.0 / (2.0 * double(h));
    }
  GradientOptions o;
  o.method = GradientMethod::Pt;
  o.sppPrimal = o.sppGradient = 4;
  GradientEngine engine(*scene, reg, {}, o);
  const int runs = 48;
  std::vector<test::MeanSE> blocks(fd.size());
  for (int i = 0; i < runs; ++i) {
    EngineSession session;
    PixelDerivativeSink sink;
    sink.index = 0;
    GradientRequest r;
    r.views = {0};
    r.seed = 100 + uint64_t(i);
    r.derivativeImage = &sink;
    engine.evaluate(r, session);
    std::vector<double> b(fd.size(), 0.0);
    for (int y = 0; y < by * B; ++y)
      for (int x = 0; x < bx * B; ++x) b[size_t((y / B) * bx + x / B)] += sink.image[size_t(y * W + x)];
    for (size_t k = 0; k < b.size(); ++k) blocks[k].add(b[k] * test::mutation());
  }
  // The reference's own noise: the bulb's share at 1024 spp, against the mean's 48 x 4.
  const double withReference = std::sqrt(1.0 + double(runs * 4) / 1024.0);
  double total = 0, totalFd = 0, totalVar = 0;
  for (size_t k = 0; k < fd.size(); ++k) {
    SCOPED_TRACE("block " + std::to_string(k));
    EXPECT_NEAR(blocks[k].mean, fd[k], test::kSigmas * blocks[k].se() * withReference + 1e-3 * std::abs(fd[k]));
    total += blocks[k].mean;
    totalFd += fd[k];
    totalVar += blocks[k].se() * blocks[k].se() * withReference * withReference;
  }
  // The whole image: every block's error in one figure, with the power it has.
  EXPECT_NEAR(total, totalFd, test::kSigmas * std::sqrt(totalVar));
  test::expectPower("derivative image, bulb intensity, image sum", std::sqrt(totalVar), totalFd);
}

}  // namespace
}  // namespace invr
