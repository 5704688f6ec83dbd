#include "core/diff/loss.h"

#include <gtest/gtest.h>

#include "core/scene/texture.h"

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
