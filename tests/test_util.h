// Shared helpers for the statistical tests: running mean/standard error, and scenes from JSON.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

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

inline std::unique_ptr<Scene> sceneFromJson(const std::string& sceneJson) {
  auto job = parseJobJson("{\"scene\": " + sceneJson + "}", "test");
  return buildJobScene(job);
}

}  // namespace invr::test
