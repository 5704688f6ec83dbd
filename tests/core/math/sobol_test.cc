// The sobol sampler (rng.h, sobol.h): stratification (nets), uniformity and independence of its
// values, and the convergence it buys against the independent sampler on a smooth and on a
// discontinuous integrand.
#include "core/math/sobol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "core/math/rng.h"
#include "test_util.h"

namespace invr {
namespace {

// Every elementary box of area 2^-m (2^a by 2^(m-a) cells, a = 0..m) holds exactly one point.
bool isNet(const std::vector<Vec2>& pts, int m) {
  for (int a = 0; a <= m; ++a) {
    const int nx = 1 << a, ny = 1 << (m - a);
    std::vector<int> count(size_t(nx) * size_t(ny), 0);
    for (const Vec2& p : pts) ++count[size_t(int(p.y * float(ny))) * size_t(nx) + size_t(int(p.x * float(nx)))];
    for (int c : count)
      if (c != 1) return false;
  }
  return true;
}

TEST(Sobol, DimensionOneTablesMatchTheDirectionNumbers) {
  for (uint32_t i : {0u, 1u, 2u, 3u, 255u, 256u, 65537u, 0x80000000u, 0xdeadbeefu, 0xffffffffu}) {
    uint32_t x = 0;
    for (int k = 0; k < 32; ++k)
      if (i & (1u << k)) x ^= sobol::kDirections1[size_t(k)];
    EXPECT_EQ(sobol::dimension1(i), x) << i;
  }
}

TEST(Sobol, TheFirstTwoDimensionsFormNets) {
  for (int m = 0; m <= 12; ++m) {
    std::vector<Vec2> pts;
    for (uint32_t i = 0; i < (1u << m); ++i) pts.push_back({sobol::toFloat(sobol::dimension0(i)), sobol::toFloat(sobol::dimension1(i))});
    EXPECT_TRUE(isNet(pts, m)) << "2^" << m << " points";
  }
}

// The index scramble keeps a block of 2^m indices a block (so a pixel's first 2^m samples are a
// whole net), and is a bijection within it.
TEST(Sobol, ScrambledIndicesOfABlockFillAnAlignedBlock) {
  for (uint64_t seed : {1ull, 0x9e3779b97f4a7c15ull, 0xdeadbeefcafef00dull})
    for (int m : {1, 4, 8}) {
      std::vector<int> seen(size_t(1) << m, 0);
      const uint32_t high = sobol::nestedScramble(0, seed) >> m;
      for (uint32_t i = 0; i < (1u << m); ++i) {
        const uint32_t s = sobol::nestedScramble(i, seed);
        EXPECT_EQ(s >> m, high);
        ++seen[s & ((1u << m) - 1)];
      }
      for (int c : seen) EXPECT_EQ(c, 1);
    }
}

// Through the Sampler: a pixel's first 2^m samples stratify each 2D slot (a net) and each 1D slot
// (one value per 1/2^m interval), in every domain.
TEST(Sobol, APixelsSamplesStratifyEverySlot) {
  for (uint64_t pixel = 0; pixel < 4; ++pixel)
    for (int m : {2, 5, 8}) {
      const uint64_t hash = RngKey{7, 3, 1, pixel, 0}.pixelHash();
      for (SampleDomain d : {SampleDomain::camera(), SampleDomain::directLight(0), SampleDomain::bsdf(2), SampleDomain::boundary()}) {
        std::vector<Vec2> slot0, slot2;
        std::vector<int> strata(size_t(1) << m, 0);
        for (uint64_t i = 0; i < (1u << m); ++i) {
          Sampler s = Sampler::forSample(SamplerKind::Sobol, hash, i);
          s.beginDomain(d);
          slot0.push_back(s.next2D());
          ++strata[size_t(s.next1D() * float(1 << m))];
          slot2.push_back(s.next2D());
        }
        EXPECT_TRUE(isNet(slot0, m)) << "pixel " << pixel << ", domain " << d.value;
        EXPECT_TRUE(isNet(slot2, m)) << "pixel " << pixel << ", domain " << d.value;
        for (int c : strata) EXPECT_EQ(c, 1);
      }
    }
}

// Each value is uniform, and values of different slots (and the two of one 2D slot) are
// uncorrelated: over n pixels, means within 5 standard errors of 1/2 (se 1/sqrt(12 n)) and
// products of two within 5 se of 1/4 (se sqrt(7/144 / n): Var(uv) = 1/9 - 1/16).
TEST(Sobol, ValuesAreUniformAndSlotsUncorrelated) {
  const int n = 1 << 16;
  for (uint64_t sample : {0ull, 5ull, 1000ull}) {
    double mean[5] = {}, prod[4] = {};
    for (int p = 0; p < n; ++p) {
      Sampler s = Sampler::forSample(SamplerKind::Sobol, RngKey{11, 0, 0, uint64_t(p), 0}.pixelHash(), sample);
      const Vec2 a = s.next2D();
      const float b = s.next1D();
      s.beginDomain(SampleDomain::directLight(0));
      const Vec2 c = s.next2D();
      const float v[5] = {a.x, a.y, b, c.x, c.y};
      for (int k = 0; k < 5; ++k) mean[k] += v[k];
      prod[0] += double(a.x) * a.y;
      prod[1] += double(a.x) * b;
      prod[2] += double(b) * c.x;
      prod[3] += double(a.y) * c.y;
    }
    // 5 SE, not 4: 27 checks here.
    for (double m : mean) EXPECT_NEAR(m / n * test::mutation(), 0.5, 5.0 / std::sqrt(12.0 * n)) << "sample " << sample;
    for (double q : prod) EXPECT_NEAR(q / n * test::mutation(), 0.25, 5.0 * std::sqrt(7.0 / 144.0 / double(n))) << "sample " << sample;
    test::expectPowerOf("means, sample " + std::to_string(sample), 5.0 / std::sqrt(12.0 * n) / 0.5);
    test::expectPowerOf("products, sample " + std::to_string(sample), 5.0 * std::sqrt(7.0 / 144.0 / double(n)) / 0.25);
  }
}

struct Rates {
  std::vector<double> rmse;  // per sample count
  double slope = 0;          // of log rmse against log N
};

// RMSE of the N-sample estimate of f's integral over [0,1)^2, over `pixels` independent pixels
// (independent scrambles), for N = 16, 64, 256, 1024, and its fitted slope.
Rates convergence(SamplerKind kind, const std::function<double(Vec2)>& f, double exact, int pixels) {
  const std::vector<int> counts{16, 64, 256, 1024};
  Rates r;
  for (int N : counts) {
    double se = 0;
    for (int p = 0; p < pixels; ++p) {
      const uint64_t hash = RngKey{uint64_t(N), 0, 0, uint64_t(p), 0}.pixelHash();
      double sum = 0;
      for (int i = 0; i < N; ++i) {
        Sampler s = Sampler::forSample(kind, hash, uint64_t(i));
        s.beginDomain(SampleDomain::bsdf(0));
        (void)s.next1D();  // the lobe choice: the 2D draw is a later slot of its domain
        sum += f(s.next2D());
      }
      se += (sum / N - exact) * (sum / N - exact);
    }
    r.rmse.push_back(std::sqrt(se / pixels));
  }
  double mx = 0, my = 0;
  for (size_t i = 0; i < counts.size(); ++i) mx += std::log(double(counts[i])) / 4, my += std::log(r.rmse[i]) / 4;
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < counts.size(); ++i) {
    const double dx = std::log(double(counts[i])) - mx;
    sxy += dx * (std::log(r.rmse[i]) - my);
    sxx += dx * dx;
  }
  r.slope = sxy / sxx;
  return r;
}

// Independent samples converge as N^-1/2. Owen-scrambled Sobol points do better: N^-3/2 on a
// smooth integrand, N^-3/4 on one with a discontinuity crossing the square; never worse. Each
// RMSE comes from 400 independent pixels, so its relative standard error is about 1/sqrt(800),
// 3.5 %: a fitted slope over N = 16..1024 is then good to about 0.01, and the ratio of two RMSEs
// to about 5 %. The bounds below are 3 or more of those from what theory predicts.
TEST(Sobol, StratifiedErrorFallsFasterOnSmoothAndNeverSlowerOnDiscontinuousIntegrands) {
  const int pixels = 400;
  auto smooth = [](Vec2 u) { return (1.0 + double(u.x)) * std::exp(double(u.y)); };
  const double smoothExact = 1.5 * (std::exp(1.0) - 1.0);
  auto disk = [](Vec2 u) { return double(u.x) * u.x + double(u.y) * u.y < 0.5 ? 1.0 : 0.0; };
  const double diskExact = M_PI / 8.0;  // a quarter disk of radius sqrt(1/2)
  const Rates indSmooth = convergence(SamplerKind::Independent, smooth, smoothExact, pixels);
  const Rates sobSmooth = convergence(SamplerKind::Sobol, smooth, smoothExact, pixels);
  const Rates indDisk = convergence(SamplerKind::Independent, disk, diskExact, pixels);
  const Rates sobDisk = convergence(SamplerKind::Sobol, disk, diskExact, pixels);
  std::printf("slopes: smooth independent %.3f sobol %.3f; disk independent %.3f sobol %.3f\n", indSmooth.slope, sobSmooth.slope,
              indDisk.slope, sobDisk.slope);
  for (size_t i = 0; i < 4; ++i)
    std::printf("N=%4d: smooth rmse %.2e / %.2e, disk rmse %.2e / %.2e (independent / sobol)\n", 16 << (2 * i), indSmooth.rmse[i],
                sobSmooth.rmse[i], indDisk.rmse[i], sobDisk.rmse[i]);
  EXPECT_NEAR(indSmooth.slope, -0.5, 0.05);
  EXPECT_NEAR(indDisk.slope, -0.5, 0.05);
  EXPECT_LT(sobSmooth.slope, -1.2);  // theory -1.5
  EXPECT_LT(sobDisk.slope, -0.6);    // theory -0.75
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_LT(sobSmooth.rmse[i], indSmooth.rmse[i]);
    EXPECT_LT(sobDisk.rmse[i], 1.15 * indDisk.rmse[i]);
  }
}

// The two samplers share the independent stream format: switching a sampler to sobol changes
// nothing for code that keeps the independent default.
TEST(Sobol, IndependentSamplesAreTheKeyedHashes) {
  const uint64_t hash = RngKey{3, 4, 5, 6, 0}.pixelHash();
  Sampler a = Sampler::forSample(SamplerKind::Independent, hash, 9), b(RngKey{3, 4, 5, 6, 9});
  a.beginDomain(SampleDomain::bsdf(3));  // no effect on independent streams
  for (int i = 0; i < 8; ++i) EXPECT_EQ(a.next1D(), b.next1D());
}

TEST(Sobol, SamplerNames) {
  EXPECT_EQ(samplerKindFromName("", "x"), SamplerKind::Independent);
  EXPECT_EQ(samplerKindFromName("sobol", "x"), SamplerKind::Sobol);
  EXPECT_STREQ(samplerKindName(SamplerKind::Sobol), "sobol");
  try {
    samplerKindFromName("halton", "render.sampler");
    FAIL() << "halton accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("render.sampler: unknown sampler 'halton'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace invr
