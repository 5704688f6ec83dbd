#include "core/math/sampling.h"

#include <gtest/gtest.h>

#include <set>

#include <cmath>
#include <vector>

#include "core/math/rng.h"
#include "test_util.h"

namespace invr {

TEST(Rng, SameKeySameStreamDifferentKeyDifferentStream) {
  Sampler a(RngKey{1, 2, 3, 4, 5}), b(RngKey{1, 2, 3, 4, 5}), c(RngKey{1, 2, 3, 4, 6});
  for (int i = 0; i < 16; ++i) {
    float va = a.next1D(), vb = b.next1D(), vc = c.next1D();
    EXPECT_EQ(va, vb);
    EXPECT_NE(va, vc);
    EXPECT_GE(va, 0.f);
    EXPECT_LT(va, 1.f);
  }
}

// Streams are keyed by (seed, stream) as a pair: no stream of any seed in 0..4095 equals any
// other (seed, stream)'s, in particular neighbouring seeds share none (seed * 2 + pass would make
// seed s's stage-1 streams seed s + 1's primal and derivative ones).
TEST(Rng, NeighbouringSeedsShareNoStream) {
  std::set<uint64_t> seen;
  std::vector<StreamId> all;
  for (uint64_t id = 1; id <= 16; ++id) all.push_back(StreamId{id});
  for (uint64_t seed = 0; seed < 4096; ++seed)
    for (StreamId s : all) EXPECT_TRUE(seen.insert(streamSeed(seed, s)).second) << "seed " << seed << " stream " << s.value;
  // The first numbers of neighbouring seeds' streams differ too (not only their keys).
  for (StreamId a : all)
    for (StreamId b : all) {
      Sampler x(RngKey{streamSeed(7, a), 3, 0, 5, 0}), y(RngKey{streamSeed(8, b), 3, 0, 5, 0});
      EXPECT_NE(x.nextBits(), y.nextBits());
    }
}

TEST(Rng, UniformMeanAndVariance) {
  // Mean of U(0,1) is 1/2 with SE sqrt(1/12/n); variance 1/12.
  const int n = 200000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    Sampler s(RngKey{7, 0, 0, uint64_t(i), 0});
    double u = s.next1D();
    sum += u;
    sum2 += u * u;
  }
  double mean = sum / n * test::mutation(), var = sum2 / n - mean * mean;
  EXPECT_NEAR(mean, 0.5, 4 * std::sqrt(1.0 / 12 / n));
  test::expectPower("mean of U(0,1)", std::sqrt(1.0 / 12 / n), 0.5);
  EXPECT_NEAR(var, 1.0 / 12, 0.002);
  test::expectPowerOf("variance of U(0,1) (a fixed tolerance of 0.002)", 0.002 * 12);
}

// A batch reserves its draws in order and hashes only those it reads (Sampler::reserve1D): the
// numbers must be the ones drawing each in turn gives, for both kinds of sampler, read in any order.
TEST(Rng, DeferredDrawsAreTheDrawsTheyStandFor) {
  for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol}) {
    for (uint64_t sample = 0; sample < 64; ++sample) {
      Sampler eager = Sampler::forSample(kind, 0x1234567 + sample, sample), deferred = eager;
      eager.beginDomain(SampleDomain::directLight(0));
      deferred.beginDomain(SampleDomain::directLight(0));
      std::vector<float> want;
      std::vector<std::pair<uint64_t, int>> reserved;  // (dimension, 1 or 2)
      for (int i = 0; i < 12; ++i) {
        const bool twoD = (i * 7 + int(sample)) % 3 == 0;
        if (twoD) {
          const Vec2 v = eager.next2D();
          want.push_back(v.x);
          want.push_back(v.y);
          reserved.push_back({deferred.reserve2D(), 2});
        } else {
          want.push_back(eager.next1D());
          reserved.push_back({deferred.reserve1D(), 1});
        }
      }
      EXPECT_EQ(deferred.dimension(), eager.dimension());
      EXPECT_EQ(deferred.next1D(), eager.next1D()) << "the draw after the batch";
      std::vector<float> got(want.size());
      size_t at = want.size();
      for (size_t i = reserved.size(); i-- > 0;) {  // read back to front
        if (reserved[i].second == 2) {
          const Vec2 v = deferred.value2D(reserved[i].first);
          got[at - 2] = v.x;
          got[at - 1] = v.y;
          at -= 2;
        } else {
          got[--at] = deferred.value1D(reserved[i].first);
        }
      }
      for (size_t i = 0; i < want.size(); ++i) ASSERT_EQ(got[i], want[i]) << samplerKindName(kind) << " sample " << sample << " draw " << i;
    }
  }
}

TEST(Distribution1D, PmfMatchesWeightsAndSamplingFrequencies) {
  std::vector<float> w = {1, 0, 3, 6};
  Distribution1D d(w);
  EXPECT_FLOAT_EQ(d.pmf(0), 0.1f);
  EXPECT_FLOAT_EQ(d.pmf(1), 0.f);
  EXPECT_FLOAT_EQ(d.pmf(3), 0.6f);
  std::vector<int> counts(4);
  const int n = 100000;
  Sampler s(RngKey{3});
  for (int i = 0; i < n; ++i) counts[d.sample(s.next1D())]++;
  EXPECT_EQ(counts[1], 0);
  for (int i : {0, 2, 3}) {
    double p = d.pmf(size_t(i));
    EXPECT_NEAR(counts[size_t(i)] / double(n) * (i == 0 ? test::mutation() : 1.0), p, 4 * std::sqrt(p * (1 - p) / n));
    test::expectPower("cell " + std::to_string(i), std::sqrt(p * (1 - p) / n), p);
  }
}

// The cell a linear scan of the same cdf picks: cdf[i] <= u < cdf[i + 1], stepping back over
// zero-probability cells (what sample() promises, whatever its lookup).
size_t cellByScan(const std::vector<float>& w, float u) {
  std::vector<double> cdf(w.size() + 1, 0.0);
  for (size_t i = 0; i < w.size(); ++i) cdf[i + 1] = cdf[i] + std::max(0.f, w[i]);
  const double norm = cdf.back();
  for (size_t i = 0; i < w.size(); ++i) cdf[i] /= norm;
  cdf.back() = 1.0;
  size_t i = 0;
  while (i + 1 < w.size() && cdf[i + 1] <= double(u)) ++i;
  while (w[i] <= 0.f && i > 0) --i;
  return i;
}

TEST(Distribution1D, LookupPicksTheCellHoldingU) {
  // Small tables are scanned, larger ones use a guide table: both must agree with the scan,
  // including at the cells' exact boundaries and around runs of empty cells; so must the inline
  // sampleIndex that light selection uses.
  for (size_t n : {1, 2, 3, 8, 9, 64, 1000}) {
    std::vector<float> w(n);
    for (size_t i = 0; i < n; ++i) w[i] = (i % 7 == 2 || i % 11 == 5) ? 0.f : float(1 + (i * i) % 13) * (i < n / 3 ? 20.f : 1.f);
    Distribution1D d(w);
    std::vector<float> us;
    Sampler s(RngKey{11, n});
    for (int k = 0; k < 4000; ++k) us.push_back(s.next1D());
    double c = 0, total = 0;
    for (float x : w) total += x;
    for (float x : w) {  // near every boundary
      c += x;
      float b = float(c / total);
      for (float v : {std::nextafter(b, 0.f), b, std::nextafter(b, 1.f)})
        if (v >= 0.f && v < 1.f) us.push_back(v);
    }
    us.push_back(0.f);
    us.push_back(0x1.fffffep-1f);
    for (float u : us) {
      float remapped = -1.f;
      size_t got = d.sample(u, &remapped);
      ASSERT_EQ(got, cellByScan(w, u)) << "n " << n << " u " << u;
      ASSERT_EQ(d.sampleIndex(u), got) << "n " << n << " u " << u;
      EXPECT_GT(d.pmf(got), 0.f);
      EXPECT_GE(remapped, 0.f);
      EXPECT_LT(remapped, 1.f);
    }
  }
}

TEST(Distribution2D, PdfIntegratesToOneAndMatchesSampling) {
  const int w = 8, h = 4;
  std::vector<float> weights(w * h);
  for (int i = 0; i < w * h; ++i) weights[size_t(i)] = float((i * 7) % 5);
  Distribution2D d(weights, w, h);
  double integral = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) integral += d.pdf({(x + 0.5f) / w, (y + 0.5f) / h}) / (w * h);
  EXPECT_NEAR(integral, 1.0, 1e-5);
  Sampler s(RngKey{9});
  for (int i = 0; i < 1000; ++i) {
    float pdf;
    Vec2 p = d.sample({s.next1D(), s.next1D()}, &pdf);
    EXPECT_GT(pdf, 0.f);
    EXPECT_NEAR(pdf, d.pdf(p), 1e-4f * pdf);
  }
}

TEST(Warps, QuarterPiSinCosMatchesLibm) {
  for (int i = -1000; i <= 1000; ++i) {
    float x = float(i) / 1000.f * (kPi / 4.f), s, c;
    sinCosQuarterPi(x, &s, &c);
    EXPECT_NEAR(s, std::sin(double(x)), 2e-7);
    EXPECT_NEAR(c, std::cos(double(x)), 2e-7);
  }
}

TEST(Warps, CosineHemisphereMatchesItsPdf) {
  // Histogram over (cos theta, phi) cells against the integral of cos(theta)/pi over each cell;
  // enough samples that the emptiest cell (1/1024 of them) shows a 10 % error (power 6.4 %: a
  // 10 % error in it fails nine times in ten, where 2,000,000 samples let INVR_TEST_MUTATE pass).
  const int nc = 8, np = 16, n = 4000000;
  std::vector<double> counts(nc * np);
  Sampler s(RngKey{5});
  for (int i = 0; i < n; ++i) {
    Vec3 v = sampleCosineHemisphere({s.next1D(), s.next1D()});
    int ci = std::min(int(v.z * nc), nc - 1);
    double phi = std::atan2(v.y, v.x) + M_PI;
    int pj = std::min(int(phi / (2 * M_PI) * np), np - 1);
    counts[size_t(ci * np + pj)]++;
  }
  counts[0] *= test::mutation();
  double worst = 0;
  for (int ci = 0; ci < nc; ++ci) {
    double c0 = double(ci) / nc, c1 = double(ci + 1) / nc;
    double p = (c1 * c1 - c0 * c0) / np;  // integral of cos/pi dcos dphi over the cell
    worst = std::max(worst, 4 * std::sqrt(p * (1 - p) / n) / p);
    for (int pj = 0; pj < np; ++pj)
      EXPECT_NEAR(counts[size_t(ci * np + pj)] / n, p, 4 * std::sqrt(p * (1 - p) / n)) << ci << "," << pj;
  }
  test::expectPowerOf("the emptiest cell", worst);
}

TEST(Warps, TriangleMapIsUniform) {
  // Uniform on the triangle: each of the 4 midpoint sub-triangles gets 1/4 of the samples.
  const int n = 200000;
  int counts[4] = {0, 0, 0, 0};
  Sampler s(RngKey{6});
  for (int i = 0; i < n; ++i) {
    Vec2 b = sampleUniformTriangle({s.next1D(), s.next1D()});
    float b0 = 1.f - b.x - b.y;
    ASSERT_GE(b.x, 0.f);
    ASSERT_GE(b.y, 0.f);
    ASSERT_GE(b0, -1e-6f);
    counts[b.x > 0.5f ? 0 : b.y > 0.5f ? 1 : b0 > 0.5f ? 2 : 3]++;
  }
  for (int k = 0; k < 4; ++k)
    EXPECT_NEAR(counts[k] / double(n) * (k == 0 ? test::mutation() : 1.0), 0.25, 4 * std::sqrt(0.25 * 0.75 / n));
  test::expectPower("each sub-triangle", std::sqrt(0.25 * 0.75 / n), 0.25);
}

TEST(Warps, CosineHemisphereStaysOnUnitHemisphere) {
  Sampler s(RngKey{4});
  for (int i = 0; i < 1000; ++i) {
    Vec3 v = sampleCosineHemisphere({s.next1D(), s.next1D()});
    EXPECT_NEAR(length(v), 1.f, 1e-5f);
    EXPECT_GE(v.z, 0.f);
  }
}

// Inversion of the binomial CDF: u on a fine stratified grid lands on each count k in a share of
// the grid that is its probability C(n,k) p^k (1-p)^(n-k) to within one cell (1 / N), in both
// tails (p above and below 1/2, where the smaller tail is walked) and at p = 0 and 1. n = 1000
// at p = 0.999: (1 - p)^n underflows, so only walking the smaller tail gets it right.
TEST(Binomial, InversionGivesEachCountItsProbability) {
  constexpr int N = 200000;
  for (int n : {1, 2, 5, 8, 33, 64, 1000})
    for (double p : {0.0, 0.03, 0.3, 0.5, 0.77, 0.999, 1.0}) {
      if (n == 1000 && p > 0.0 && p < 0.999) continue;  // long walks; the small n cover these p
      std::vector<int> hits(size_t(n) + 1, 0);
      for (int i = 0; i < N; ++i) {
        const int k = sampleBinomial(n, p, (float(i) + 0.5f) / float(N));
        ASSERT_GE(k, 0);
        ASSERT_LE(k, n);
        ++hits[size_t(k)];
      }
      for (int k = 0; k <= n; ++k) {
        const double exact = p == 0.0 ? (k == 0) : p == 1.0 ? (k == n)
                             : std::exp(std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0) + k * std::log(p) + (n - k) * std::log1p(-p));
        EXPECT_NEAR(double(hits[size_t(k)]) / N, exact, 1.5 / N + 1e-9) << "n " << n << " p " << p << " k " << k;
      }
    }
}

}  // namespace invr
