// Warps from the unit square and discrete distributions.
#pragma once

#include <cmath>
#include <span>
#include <vector>

#include "core/math/vec.h"

namespace invr {

// sin and cos for |x| <= pi/4 by their Taylor polynomials (through x^9 and x^10): truncation
// error < 2e-9, below float precision, with no range reduction.
inline void sinCosQuarterPi(float x, float* s, float* c) {
  float x2 = x * x;
  *s = x * (1.f + x2 * (-1.f / 6.f + x2 * (1.f / 120.f + x2 * (-1.f / 5040.f + x2 * (1.f / 362880.f)))));
  *c = 1.f + x2 * (-0.5f + x2 * (1.f / 24.f + x2 * (-1.f / 720.f + x2 * (1.f / 40320.f + x2 * (-1.f / 3628800.f)))));
}

// A Binomial(n, p) count from one uniform u in [0, 1), by inversion of its CDF (O(n p) steps;
// the smaller tail is walked, so p^n or (1-p)^n >= 2^-n stays representable for n <= 1000).
inline int sampleBinomial(int n, double p, float u) {
  if (!(p > 0.0) || n <= 0) return 0;
  if (p >= 1.0) return n;
  if (p > 0.5) return n - sampleBinomial(n, 1.0 - p, 1.f - u);  // 1 - u in (0, 1]: the same inversion from the top
  const double q = 1.0 - p, ratio = p / q;
  double pk = 1.0;  // q^n by squaring: std::pow was 7 % of an oxalis ReSTIR step
  double b = q;
  for (int e = n; e > 0; e >>= 1) {
    if (e & 1) pk *= b;
    b *= b;
  }
  double cdf = pk;
  int k = 0;
  while (double(u) >= cdf && k < n) {
    pk *= double(n - k) / double(k + 1) * ratio;
    ++k;
    cdf += pk;
  }
  return k;
}

inline Vec3 sampleCosineHemisphere(Vec2 u) {
  // Concentric disk mapping (Shirley and Chiu), then lift to the hemisphere (Malley's method).
  float a = 2.f * u.x - 1.f, b = 2.f * u.y - 1.f;
  if (a == 0.f && b == 0.f) return {0.f, 0.f, 1.f};
  float r, s, c, x, y;
  if (a * a > b * b) {
    r = a;
    sinCosQuarterPi((kPi / 4.f) * (b / a), &s, &c);
    x = r * c; y = r * s;
  } else {
    r = b;
    sinCosQuarterPi((kPi / 4.f) * (a / b), &s, &c);  // angle pi/2 - t: cos and sin swap
    x = r * s; y = r * c;
  }
  return {x, y, safeSqrt(1.f - x * x - y * y)};
}
inline float cosineHemispherePdf(float cosTheta) { return cosTheta > 0.f ? cosTheta * kInvPi : 0.f; }

inline Vec3 sampleUniformSphere(Vec2 u) {
  float z = 1.f - 2.f * u.x, r = safeSqrt(1.f - z * z), phi = 2.f * kPi * u.y;
  return {r * std::cos(phi), r * std::sin(phi), z};
}
inline constexpr float kUniformSpherePdf = 1.f / (4.f * kPi);

// Uniform barycentrics (b1, b2) on a triangle; b0 = 1 - b1 - b2. Heitz's low-distortion
// square-to-triangle map (2019): area-preserving and free of square roots.
inline Vec2 sampleUniformTriangle(Vec2 u) {
  float b0, b1;
  if (u.y > u.x) {
    b0 = 0.5f * u.x;
    b1 = u.y - b0;
  } else {
    b1 = 0.5f * u.y;
    b0 = u.x - b1;
  }
  return {b0, b1};
}

// Piecewise-constant 1D distribution over n cells with O(log n) sampling.
class Distribution1D {
 public:
  Distribution1D() = default;
  explicit Distribution1D(std::span<const float> weights);
  size_t size() const { return pmf_.size(); }
  double total() const { return total_; }
  float pmf(size_t i) const { return pmf_[i]; }
  // Returns the cell index; remapped gets u rescaled into [0,1) within the cell.
  size_t sample(float u, float* remapped = nullptr) const;
  // sample(u) without the remap, inline for the few-cell distributions that light selection mostly
  // sees (one call per RIS candidate); the same cell as sample(u).
  size_t sampleIndex(float u) const {
    const size_t n = pmf_.size();
    if (n == 1) return 0;
    if (n > 8) return sample(u);
    size_t i = 0;
    for (size_t j = 1; j < n; ++j) i += size_t(cdf_[j] <= double(u));
    while (pmf_[i] == 0.f && i > 0) --i;
    return i;
  }

 private:
  std::vector<float> pmf_;
  std::vector<float> invPmf_;  // so the remap needs no division
  std::vector<double> cdf_;
  std::vector<uint32_t> guide_;  // more than 8 cells: guide_[k] is the cell holding k / size
  double total_ = 0;
};

// Piecewise-constant 2D distribution on [0,1]^2 (marginal over rows, conditional per row).
class Distribution2D {
 public:
  Distribution2D() = default;
  Distribution2D(std::span<const float> weights, int width, int height);
  // Returns a point in [0,1)^2 and its density with respect to area on [0,1]^2.
  Vec2 sample(Vec2 u, float* pdf) const;
  float pdf(Vec2 p) const;

 private:
  int w_ = 0, h_ = 0;
  std::vector<Distribution1D> rows_;
  Distribution1D marginal_;
};

}  // namespace invr
