// The convergence signal every job has, photographs as targets included: an exponential moving
// average of the one-render loss (GradientStats.primal_loss). The unbiased loss (I1 - T)(I2 - T)
// is noisy and may be negative; this one is biased by the render's noise but falls steadily as
// the renders approach the targets.
#pragma once

#include <cmath>
#include <cstdint>

namespace invr {

class SmoothedLoss {
 public:
  static constexpr double kWeight = 0.9;  // about a ten-step window

  // Adds one step's value; returns the bias-corrected average so far (as Adam corrects its
  // moments: the first steps are not pulled towards 0). Non-finite values are skipped.
  double add(double value) {
    if (std::isfinite(value)) {
      ++count_;
      mean_ = kWeight * mean_ + (1 - kWeight) * value;
    }
    return value_();
  }
  double value() const { return value_(); }

 private:
  double value_() const { return count_ ? mean_ / (1 - std::pow(kWeight, double(count_))) : std::nan(""); }
  double mean_ = 0;
  uint64_t count_ = 0;
};

}  // namespace invr
