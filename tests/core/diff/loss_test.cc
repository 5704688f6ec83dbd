#include "core/diff/loss.h"

#include <gtest/gtest.h>

#include "core/math/rng.h"
#include "core/image/texture.h"
#include "test_util.h"

#include <cstdio>

namespace invr {
namespace {

TEST(Loss, AdjointsMatchFiniteDifferences) {
  Image I(4, 3, 3), T(4, 3, 3);
  for (size_t i = 0; i < I.data().size(); ++i) {
    I.data()[i] = 0.1f + 0.07f * float(i % 11);
    T.data()[i] = 0.4f + 0.03f * float(i % 5);
  }
  for (LossKind k : {LossKind::L2, LossKind::RelativeL2, LossKind::L1}) {
    Image adj;
    imageLoss(k, I, T, &adj, 2);
    for (size_t i : {size_t(0), size_t(7), size_t(20)}) {
      Image p = I, m = I;
      const float h = 1e-3f;
      p.data()[i] += h;
      m.data()[i] -= h;
      double fd = (imageLoss(k, p, T, nullptr, 2) - imageLoss(k, m, T, nullptr, 2)) / (2 * h);
      EXPECT_NEAR(adj.data()[i], fd, 1e-4 * std::abs(fd) + 1e-6) << lossName(k) << " " << i;
    }
  }
  EXPECT_THROW(lossKindFromName("l3"), std::exception);
}

// The reported loss: from two independent noisy renders of the image E, (I1 - T)(I2 - T) has
// expectation loss(E) (l2, relative_l2), while one render's (I - T)^2 has loss(E) + its variance.
// Means over 4000 noise draws (uniform noise of half-width 0.3: variance 0.03 per value), within
// 4 standard errors; the single-render figure is off by the variance, far outside them.
TEST(Loss, TwoRenderLossIsUnbiased) {
  Image E(4, 3, 3), T(4, 3, 3);
  for (size_t i = 0; i < E.data().size(); ++i) {
    E.data()[i] = 0.3f + 0.05f * float(i % 7);
    T.data()[i] = 0.4f + 0.03f * float(i % 5);
  }
  for (LossKind k : {LossKind::L2, LossKind::RelativeL2}) {
    const double truth = imageLoss(k, E, T, nullptr);
    test::MeanSE two, one;
    Sampler noise(RngKey{11, 0, 0, 0, 0});
    for (int r = 0; r < 4000; ++r) {
      Image a = E, b = E;
      for (float& v : a.data()) v += 0.6f * (noise.next1D() - 0.5f);
      for (float& v : b.data()) v += 0.6f * (noise.next1D() - 0.5f);
      two.add(unbiasedImageLoss(k, a, b, T));
      one.add(imageLoss(k, a, T, nullptr));
    }
    two.mean *= test::mutation();
    std::printf("%s: loss(E) %.5f, two renders %.5f (se %.5f), one render %.5f\n", lossName(k), truth, two.mean, two.se(), one.mean);
    EXPECT_NEAR(two.mean, truth, test::kSigmas * two.se()) << lossName(k);
    test::expectPower(std::string(lossName(k)) + ": two-render loss", two.se(), truth);
    EXPECT_GT(std::abs(one.mean - truth), 10 * test::kSigmas * one.se()) << lossName(k) << ": the single-render bias should show";
  }
}

TEST(TextureAdjoint, BilinearWeightsAreTheDerivative) {
  auto img = std::make_shared<Image>(5, 4, 3);
  for (size_t i = 0; i < img->data().size(); ++i) img->data()[i] = float(i % 13) / 13.f;
  Texture t(img, 1.f);
  Vec2 uv(0.37f, 0.81f);
  float sum = 0.f;
  t.forEachTexel(uv, [&](int x, int y, float w) {
    sum += w;
    const float h = 1e-2f;
    float old = img->at(x, y, 1);
    img->at(x, y, 1) = old + h;
    float up = t.eval(uv).y;
    img->at(x, y, 1) = old - h;
    float down = t.eval(uv).y;
    img->at(x, y, 1) = old;
    EXPECT_NEAR((up - down) / (2 * h), w, 1e-4f);
  });
  EXPECT_NEAR(sum, 1.f, 1e-6f);
}

}  // namespace
}  // namespace invr
