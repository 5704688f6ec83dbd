#include "core/limits.h"

#include <cstdio>

namespace invr {

const InputLimits& inputLimits() {
  static const InputLimits limits;
  return limits;
}

void rethrowWithMessage(const InputError& original, const std::string& message) {
  if (dynamic_cast<const ResourceError*>(&original)) throw ResourceError(message);
  throw InputError(message);
}

std::string humanBytes(uint64_t bytes) {
  const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 4) v /= 1024.0, ++u;
  char b[48];
  if (u == 0)
    std::snprintf(b, sizeof b, "%llu bytes", static_cast<unsigned long long>(bytes));
  else
    std::snprintf(b, sizeof b, "%.3g %s", v, units[u]);
  return b;
}

void MemoryBudget::charge(uint64_t bytes, const std::string& what) {
  if (bytes > limit_ || used_ > limit_ - bytes)
    throw ResourceError(what + ": needs " + humanBytes(bytes) + ", which exceeds the job's memory budget of " + humanBytes(limit_) +
                        " (" + humanBytes(used_) + " already used)");
  used_ += bytes;
}

}  // namespace invr
