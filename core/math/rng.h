// Counter-based random numbers: every value is a pure function of its key
// (seed, step, view, pixel, sample) and a running dimension index, so images and gradients do not
// depend on thread count, scheduling or worker count.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/math/sobol.h"
#include "core/math/vec.h"

namespace invr {

// SplitMix64 finaliser: a strong 64-bit bijective mixer.
inline constexpr uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// One purpose random numbers serve within a job (a pass, a boundary term, the targets, ...).
// The engine's own passes have small numbers, declared beside the code that draws from them;
// registered family members (boundary terms) derive theirs from their registered name (named()),
// and registration checks them unique. No two purposes share one.
struct StreamId {
  uint64_t value;
  constexpr bool operator==(const StreamId&) const = default;
  // FNV-1a of the name with the top bit set: never one of the engine's small numbers.
  static constexpr StreamId named(std::string_view name) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (char c : name) h = (h ^ uint64_t(uint8_t(c))) * 0x100000001b3ull;
    return {h | (1ull << 63)};
  }
};

// The engine's own passes use the numbers 1 to this (gradient_engine.h, pixel_sampler.h,
// problem.h, image_error.h); a test checks them unique.
inline constexpr uint64_t kLastEngineStream = 11;

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

// How the values of a pixel's samples relate to each other. Independent: every value is its own
// hash. Sobol: sample i of a pixel is point i of an Owen-scrambled Sobol sequence, one shuffled
// 2D sequence per slot (see SampleDomain), so a pixel's samples stratify every 1D and 2D draw.
// Both are counter-based; each value on its own is uniform, so every estimator stays unbiased.
enum class SamplerKind : uint8_t { Independent, Sobol };
const char* samplerKindName(SamplerKind kind);
// "independent" or "sobol" (empty: independent); throws InputError naming `field` otherwise.
SamplerKind samplerKindFromName(const std::string& name, const std::string& field);

// Where a camera sample's values go. A purpose opens its domain before it draws, and its k-th draw
// takes slot k of that domain; two samples of a pixel that draw for the same purpose therefore
// use the same slots (which is what the sobol sampler stratifies across samples), and a purpose
// drawing a varying number of values cannot shift the slots of the others. A new estimator
// declares its own domain here rather than reusing another's.
struct SampleDomain {
  uint32_t value;
  static constexpr SampleDomain camera() { return {0}; }  // the position on the film (one 2D draw)
  // Per path vertex (depth 0 is the first hit): the direct-light strategy (light choice, light
  // point, each RIS candidate), the BSDF sample, Russian roulette.
  static constexpr SampleDomain directLight(int depth) { return {1u + 3u * uint32_t(depth)}; }
  static constexpr SampleDomain bsdf(int depth) { return {2u + 3u * uint32_t(depth)}; }
  static constexpr SampleDomain roulette(int depth) { return {3u + 3u * uint32_t(depth)}; }
  // A boundary term's sample (edge, side, light point): one sample per boundary sample index.
  static constexpr SampleDomain boundary() { return {0xfffffu}; }
};

// A stream of uniforms for one key. Independent: dimension d of key k is
// mix64(hash(k) + d * golden), with random access and no state shared between threads.
class Sampler {
 public:
  Sampler() = default;
  explicit Sampler(const RngKey& key) : base_(key.hash()) {}
  explicit Sampler(uint64_t base) : base_(base) {}
  // Sample `sample` of the pixel (or boundary term) whose RngKey::pixelHash is `pixelHash`.
  static Sampler forSample(SamplerKind kind, uint64_t pixelHash, uint64_t sample) {
    if (kind == SamplerKind::Independent) return Sampler(RngKey::withSample(pixelHash, sample));
    Sampler s(mix64(pixelHash ^ 0x5851f42d4c957f2dull));  // every sample of the pixel: one scramble
    s.kind_ = SamplerKind::Sobol;
    s.index_ = uint32_t(sample);
    return s;
  }

  // Sample key.pixel of a set of samples not tied to pixels (a boundary term's samples in one view):
  // the key itself when independent; for sobol, point key.pixel of one sequence per (seed, step,
  // view, sample) of the key, its draws in the boundary domain.
  static Sampler forSampleSet(SamplerKind kind, const RngKey& key) {
    if (kind == SamplerKind::Independent) return Sampler(key);
    Sampler s = forSample(kind, RngKey{key.seed, key.step, key.view, ~key.sample, 0}.pixelHash(), key.pixel);
    s.beginDomain(SampleDomain::boundary());
    return s;
  }

  // Opens a domain: the next draws take its slots from the first (sobol); independent streams
  // need no alignment and keep drawing in order.
  void beginDomain(SampleDomain d) {
    if (kind_ == SamplerKind::Sobol) dim_ = uint64_t(d.value) << 24;
  }

  uint64_t nextBits() {
    if (kind_ == SamplerKind::Sobol) return uint64_t(sobolSlot(nullptr)) << 32;
    return mix64(base_ + (dim_++) * 0x9e3779b97f4a7c15ull);
  }
  // Uniform in [0, 1): the top 24 bits give exactly representable floats below 1.
  float next1D() {
    if (kind_ == SamplerKind::Sobol) return sobol::toFloat(sobolSlot(nullptr));
    return float(nextBits() >> 40) * 0x1p-24f;
  }
  double next1Dd() { return double(nextBits() >> 11) * 0x1p-53; }
  // Two values drawn together (a point on a light, a BSDF direction, a film position): one 2D slot
  // of the sobol sampler, two draws in order of the independent one.
  Vec2 next2D() {
    if (kind_ == SamplerKind::Sobol) {
      uint32_t y = 0;
      uint32_t x = sobolSlot(&y);
      return {sobol::toFloat(x), sobol::toFloat(y)};
    }
    float x = next1D();
    return {x, next1D()};
  }
  // Deferred draws: reserve1D/reserve2D take the dimensions next1D/next2D would take and return
  // the first; value1D/value2D(dim) give the numbers those draws would have returned. A batch of
  // candidates reserves every draw in order (so the dimensions, and the numbers, are the same as
  // drawing them one by one) and computes only the ones it uses: a delta light's point draw and
  // the pick of a zero-weight candidate cost nothing.
  uint64_t reserve1D() { return dim_++; }
  uint64_t reserve2D() {
    const uint64_t d = dim_;
    dim_ += kind_ == SamplerKind::Sobol ? 1 : 2;
    return d;
  }
  float value1D(uint64_t dim) const {
    if (kind_ == SamplerKind::Sobol) return sobol::toFloat(sobolSlotAt(dim, nullptr));
    return float(mix64(base_ + dim * 0x9e3779b97f4a7c15ull) >> 40) * 0x1p-24f;
  }
  Vec2 value2D(uint64_t dim) const {
    if (kind_ == SamplerKind::Sobol) {
      uint32_t y = 0;
      uint32_t x = sobolSlotAt(dim, &y);
      return {sobol::toFloat(x), sobol::toFloat(y)};
    }
    return {value1D(dim), value1D(dim + 1)};
  }
  uint64_t dimension() const { return dim_; }
  SamplerKind kind() const { return kind_; }
  // A child stream for a sub-task (e.g. one RIS candidate) that cannot collide with this one. A
  // sobol child keeps the sample index: the children of a pixel's samples stratify together.
  Sampler fork(uint64_t tag) const {
    Sampler s(mix64(base_ ^ mix64(tag + 0x632be59bd9b4e019ull)));
    s.kind_ = kind_;
    s.index_ = index_;
    return s;
  }

 private:
  // The next slot's point: dimension 0 (and dimension 1 into *second), both scrambled, at the
  // sample index shuffled for this slot.
  uint32_t sobolSlot(uint32_t* second) { return sobolSlotAt(dim_++, second); }
  uint32_t sobolSlotAt(uint64_t dim, uint32_t* second) const {
    const uint64_t h = mix64(base_ + dim * 0x9e3779b97f4a7c15ull);
    const uint32_t i = sobol::nestedScramble(index_, h);
    if (second) *second = sobol::nestedScramble(sobol::dimension1(i), mix64(h ^ 0xd6e8feb86659fd93ull));
    return sobol::nestedScramble(sobol::dimension0(i), mix64(h + 0x2545f4914f6cdd1dull));
  }

  uint64_t base_ = 0;
  uint64_t dim_ = 0;
  uint32_t index_ = 0;
  SamplerKind kind_ = SamplerKind::Independent;
};

}  // namespace invr
