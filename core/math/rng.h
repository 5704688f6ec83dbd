// Counter-based random numbers: every value is a pure function of its key
// (seed, step, view, pixel, sample) and a running dimension index, so images and gradients do not
// depend on thread count, scheduling or worker count.
#pragma once

#include <cstdint>

namespace invr {

// SplitMix64 finaliser: a strong 64-bit bijective mixer.
inline constexpr uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// One purpose random numbers serve within a job (a pass, a boundary term, the targets, ...).
// Each id is declared beside the code that draws from it; no two purposes share one.
struct StreamId {
  uint64_t value;
  constexpr bool operator==(const StreamId&) const = default;
};

// The seed of one stream of a job: (job seed, stream) hashed as a pair. Arithmetic such as
// seed * 2 + pass would make seed s's third stream seed s + 1's first, so runs with neighbouring
// seeds would share numbers and not be independent.
inline constexpr uint64_t streamSeed(uint64_t seed, StreamId stream) {
  return mix64(mix64(seed ^ 0x2545f4914f6cdd1dull) + stream.value * 0x9e3779b97f4a7c15ull);
}

struct RngKey {
  uint64_t seed = 0;
  uint64_t step = 0;
  uint64_t view = 0;
  uint64_t pixel = 0;
  uint64_t sample = 0;

  // Hash of everything but the sample index; loops over samples compute it once per pixel.
  constexpr uint64_t pixelHash() const {
    uint64_t h = mix64(seed + 0x9e3779b97f4a7c15ull);
    h = mix64(h ^ (step * 0xd1b54a32d192ed03ull));
    h = mix64(h ^ (view * 0xaef17502108ef2d9ull));
    return mix64(h ^ (pixel * 0xf58e7a3e3ee48e0bull));
  }
  static constexpr uint64_t withSample(uint64_t pixelHash, uint64_t sample) {
    return mix64(pixelHash ^ (sample * 0x8cb92ba72f3d8dd7ull));
  }
  constexpr uint64_t hash() const { return withSample(pixelHash(), sample); }
};

// A stream of uniforms for one key. Dimension d of key k is mix64(hash(k) + d * golden):
// random access, no state shared between threads.
class Sampler {
 public:
  Sampler() = default;
  explicit Sampler(const RngKey& key) : base_(key.hash()) {}
  explicit Sampler(uint64_t base) : base_(base) {}

  uint64_t nextBits() { return mix64(base_ + (dim_++) * 0x9e3779b97f4a7c15ull); }
  // Uniform in [0, 1): the top 24 bits give exactly representable floats below 1.
  float next1D() { return float(nextBits() >> 40) * 0x1p-24f; }
  double next1Dd() { return double(nextBits() >> 11) * 0x1p-53; }
  uint64_t dimension() const { return dim_; }
  // A child stream for a sub-task (e.g. one RIS candidate) that cannot collide with this one.
  Sampler fork(uint64_t tag) const { return Sampler(mix64(base_ ^ mix64(tag + 0x632be59bd9b4e019ull))); }

 private:
  uint64_t base_ = 0;
  uint64_t dim_ = 0;
};

}  // namespace invr
