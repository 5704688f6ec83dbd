// A float widened to the double of its shortest decimal form, for text output: 0.1f becomes 0.1,
// where a plain widening prints 0.10000000149011612 in JSON.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdlib>

namespace invr {

inline double shortestDecimal(float v) {
  if (!std::isfinite(v)) return double(v);
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf - 1, v);
  *r.ptr = '\0';
  return std::strtod(buf, nullptr);
}

}  // namespace invr
