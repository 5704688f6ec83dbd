// Owen-scrambled Sobol points (the `sobol` sampler of rng.h): the first two dimensions of the
// Sobol sequence, scrambled by a hash-based nested uniform permutation of their binary digits
// (Laine & Karras 2011; Burley 2020). The same permutation applied to a sample index shuffles the
// order of the points without breaking their stratification, which decorrelates the dimension
// pairs of one sample (each pair is its own shuffled 2D sequence, "padding").
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace invr::sobol {

inline constexpr uint32_t reverseBits(uint32_t v) {
  v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
  v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
  v = ((v >> 4) & 0x0f0f0f0fu) | ((v & 0x0f0f0f0fu) << 4);
  v = ((v >> 8) & 0x00ff00ffu) | ((v & 0x00ff00ffu) << 8);
  return (v >> 16) | (v << 16);
}

// Dimension 1's direction numbers as 32-bit fixed point: primitive polynomial x + 1, so
// m_1 = 1 and m_k = 2 m_{k-1} xor m_{k-1}; v_k = m_k / 2^k. (Dimension 0 is van der Corput.)
inline constexpr std::array<uint32_t, 32> kDirections1 = [] {
  std::array<uint32_t, 32> v{};
  uint64_t m = 1;
  for (int k = 1; k <= 32; ++k) {
    v[std::size_t(k - 1)] = uint32_t(m << (32 - k));
    m = (m << 1) ^ m;
  }
  return v;
}();

// Dimension 1 is linear over GF(2) in the index's bits: the xor of one table entry per index
// byte (4 x 256 entries) instead of one direction number per set bit.
inline constexpr std::array<uint32_t, 1024> kDimension1Bytes = [] {
  std::array<uint32_t, 1024> t{};
  for (int b = 0; b < 4; ++b)
    for (uint32_t v = 0; v < 256; ++v) {
      uint32_t x = 0;
      for (int k = 0; k < 8; ++k)
        if (v & (1u << k)) x ^= kDirections1[std::size_t(8 * b + k)];
      t[std::size_t(256 * b) + v] = x;
    }
  return t;
}();

// Point i of the sequence, as 32-bit fractions.
inline constexpr uint32_t dimension0(uint32_t i) { return reverseBits(i); }
inline constexpr uint32_t dimension1(uint32_t i) {
  return kDimension1Bytes[i & 255u] ^ kDimension1Bytes[256u + ((i >> 8) & 255u)] ^ kDimension1Bytes[512u + ((i >> 16) & 255u)] ^
         kDimension1Bytes[768u + (i >> 24)];
}

// A nested uniform scramble of v's digits, most significant first: output bit j is input bit j
// flipped by a function of the bits above it (and the seed). In reversed bit order that is a map
// whose bit k depends only on bits below k: additions, odd products and xors with even products
// all have that form and are bijections. The multipliers come from the seed, so different seeds
// give differently shaped permutations, not only different flips.
inline constexpr uint32_t nestedScramble(uint32_t v, uint64_t seed) {
  uint32_t x = reverseBits(v);
  x += uint32_t(seed);
  x *= uint32_t(seed >> 32) | 1u;
  x ^= x * 0x6a5d39eau;  // even constants: bit k gains a function of bits below k
  x += uint32_t(seed >> 16) & 0xffff0000u;
  x ^= x * 0xc2b2ae34u;
  x *= 0x9e3779b9u | 1u;
  x ^= x * (uint32_t(seed >> 40) << 1);
  return reverseBits(x);
}

// A 32-bit fraction as a float in [0, 1): the top 24 bits, exactly representable.
inline constexpr float toFloat(uint32_t x) { return float(x >> 8) * 0x1p-24f; }

}  // namespace invr::sobol
