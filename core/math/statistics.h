// The mean of independent samples and its standard error, accumulated one sample at a time
// (Welford's update: no cancellation when the mean is large against the spread).
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>

namespace invr {

class MeanSe {
 public:
  void add(double x) {
    ++n_;
    const double d = x - mean_;
    mean_ += d / double(n_);
    m2_ += d * (x - mean_);
  }
  size_t count() const { return n_; }
  double mean() const { return mean_; }
  // The sample variance (Bessel's correction); 0 below two samples.
  double variance() const { return n_ > 1 ? m2_ / double(n_ - 1) : 0.0; }
  // The standard error of the mean; infinite below two samples (nothing is known of the spread).
  double se() const { return n_ > 1 ? std::sqrt(variance() / double(n_)) : std::numeric_limits<double>::infinity(); }

 private:
  size_t n_ = 0;
  double mean_ = 0, m2_ = 0;
};

}  // namespace invr
