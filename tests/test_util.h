// Shared helpers for the statistical tests: running mean/standard error, and scenes from JSON.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>
#include <algorithm>

#include "core/geometry/mesh.h"
#include "core/io/job_io.h"
#include "core/scene/scene_builder.h"

namespace invr::test {

// Welford accumulator for independent samples.
struct MeanSE {
  double n = 0, mean = 0, m2 = 0;
  void add(double x) {
    n += 1;
    double d = x - mean;
    mean += d / n;
    m2 += d * (x - mean);
  }
  double variance() const { return n > 1 ? m2 / (n - 1) : 0; }
  double se() const { return std::sqrt(variance() / n); }
};

// Every statistical tolerance in the suite is k standard errors with k = 4: a correct estimator
// fails with probability ~6e-5 per check (two-sided normal tail), and seeds are fixed so a run
// is reproducible.
inline constexpr double kSigmas = 4.0;

// The mutation check of the statistical tests (issue 57): INVR_TEST_MUTATE=1.1 multiplies every
// estimate they compare with a reference by 1.1 (a 10 % error), and each must then fail.
inline double mutation() {
  static const double factor = [] {
    const char* v = std::getenv("INVR_TEST_MUTATE");
    return v && *v ? std::atof(v) : 1.0;
  }();
  return factor;
}

// The power of a comparison at that threshold: the smallest error, relative to `reference`, that
// it would detect, kSigmas * combinedSe / |reference| (issue 57). Every statistical test prints it
// ("power 6.1 % (needs <= 10 %)") and fails when it is weaker than it claims: 10 % unless the test
// says why not.
inline double expectPowerOf(const std::string& what, double power, double claim = 0.10) {
  std::printf("%s: power %.1f %% (needs <= %.0f %%)\n", what.c_str(), 100 * power, 100 * claim);
  EXPECT_LE(power, claim) << what << ": a " << 100 * claim << " % error would pass unseen (power " << 100 * power << " %)";
  return power;
}
inline double expectPower(const std::string& what, double combinedSe, double reference, double claim = 0.10) {
  return expectPowerOf(what, std::abs(reference) > 0 ? kSigmas * combinedSe / std::abs(reference) : INFINITY, claim);
}

// A PNG whose header declares w x h 8-bit RGB pixels, followed by 4 bytes of (not decodable)
// pixel data: a reader that trusts the header allocates w x h before it finds out.
inline std::string pngDeclaringSize(uint32_t w, uint32_t h) {
  auto crc32 = [](const std::string& bytes) {
    uint32_t c = 0xffffffffu;
    for (unsigned char b : bytes) {
      c ^= b;
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return ~c;
  };
  auto be = [](uint32_t v) { return std::string{char(v >> 24), char(v >> 16), char(v >> 8), char(v)}; };
  std::string ihdr = "IHDR" + be(w) + be(h) + std::string{8, 2, 0, 0, 0};
  std::string idat = "IDAT" + std::string("\x78\x9c\x00\x00", 4);
  std::string iend = "IEND";
  return std::string("\x89PNG\r\n\x1a\n", 8) + be(13) + ihdr + be(crc32(ihdr)) + be(4) + idat + be(crc32(idat)) + be(0) + iend +
         be(crc32(iend));
}

// Per-pixel statistics of an image estimator over independent repetitions: the mean of each
// pixel's luminance and the standard error of that mean from the pixel's own spread.
struct PixelStats {
  int width = 0, height = 0;
  std::vector<MeanSE> pixel;
  PixelStats(int w, int h) : width(w), height(h), pixel(size_t(w) * size_t(h)) {}
  template <class Image>
  void add(const Image& im) {
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        auto c = im.rgb(x, y);
        pixel[size_t(y) * size_t(width) + size_t(x)].add(0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z);
      }
  }
};

// Two estimators of the same image compared region by region (block x block pixels): for each
// region the difference of the means in units of its standard error, from the pixels' own
// variances (independent pixels: the region's variance is the sum of theirs). Also the regions'
// relative standard errors, which say how small a bias the comparison can see.
struct RegionComparison {
  std::vector<double> z, relativeSe, mean;
  double maxAbsZ() const {
    double m = 0;
    for (double v : z) m = std::max(m, std::abs(v));
    return m;
  }
  double meanZ2() const {
    double s = 0;
    for (double v : z) s += v * v;
    return z.empty() ? 0 : s / double(z.size());
  }
};

// The relative SE that three regions in four stay under (the power of a region comparison is
// kSigmas times it).
inline double upperQuartile(std::vector<double> v) {
  if (v.empty()) return INFINITY;
  std::sort(v.begin(), v.end());
  return v[v.size() * 3 / 4];
}

inline RegionComparison compareRegions(const PixelStats& a, const PixelStats& b, int block) {
  RegionComparison out;
  for (int by = 0; by + block <= a.height; by += block)
    for (int bx = 0; bx + block <= a.width; bx += block) {
      double ma = 0, mb = 0, va = 0, vb = 0;
      for (int y = by; y < by + block; ++y)
        for (int x = bx; x < bx + block; ++x) {
          const MeanSE& pa = a.pixel[size_t(y) * size_t(a.width) + size_t(x)];
          const MeanSE& pb = b.pixel[size_t(y) * size_t(b.width) + size_t(x)];
          ma += pa.mean;
          mb += pb.mean;
          va += pa.se() * pa.se();
          vb += pb.se() * pb.se();
        }
      double se = std::sqrt(va + vb);
      if (!(se > 0)) continue;  // a region both estimators see as exactly constant (black)
      ma *= mutation();          // `a` is the estimate under test, `b` the reference
      out.z.push_back((ma - mb) / se);
      out.relativeSe.push_back(mb != 0 ? se / std::abs(mb) : 0);
      out.mean.push_back(mb);
    }
  return out;
}

inline std::unique_ptr<Scene> sceneFromJson(const std::string& sceneJson) {
  auto job = parseJobJson("{\"scene\": " + sceneJson + "}", "test");
  return buildJobScene(job);
}

// A closed mesh's signed volume (divergence theorem): positive when its faces point outward.
inline double signedVolume(const TriangleMesh& m) {
  double v = 0;
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    Vec3 a = m.positions[m.indices[3 * t]], b = m.positions[m.indices[3 * t + 1]], c = m.positions[m.indices[3 * t + 2]];
    v += dot(a, cross(b, c)) / 6.0;
  }
  return v;
}

}  // namespace invr::test
