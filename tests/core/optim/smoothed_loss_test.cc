// The smoothed image loss: an exponential moving average, bias-corrected, skipping non-finite values.
#include "core/optim/smoothed_loss.h"

#include <gtest/gtest.h>

#include <cmath>

namespace invr {
namespace {

TEST(SmoothedLoss, ConstantInputIsReportedFromTheFirstStep) {
  SmoothedLoss s;
  EXPECT_TRUE(std::isnan(s.value()));
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(s.add(2.5), 2.5, 1e-12);  // bias-corrected: no pull towards 0
}

TEST(SmoothedLoss, WeightsFallGeometricallyAndNonFiniteValuesAreSkipped) {
  SmoothedLoss s;
  const double x[] = {4.0, 1.0, 2.0};
  double num = 0, den = 0;
  for (int k = 0; k < 3; ++k) {
    s.add(x[k]);
    if (k == 1) s.add(std::nan(""));
    // Step k's value weighs 0.9^(n-1-k) among the n seen.
  }
  for (int k = 0; k < 3; ++k) {
    const double w = std::pow(SmoothedLoss::kWeight, 2 - k);
    num += w * x[k];
    den += w;
  }
  EXPECT_NEAR(s.value(), num / den, 1e-12);
}

}  // namespace
}  // namespace invr
