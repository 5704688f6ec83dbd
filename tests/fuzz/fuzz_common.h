// Shared by the fuzz targets: what counts as an expected outcome and how a broken promise is
// reported. A target returns normally when the code under test accepts its input or rejects it
// with invr::InputError (ResourceError included); any other exception, a sanitizer report or a
// FUZZ_CHECK that fails is a finding (libFuzzer saves the input as a crash artifact).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/error.h"

namespace invr::fuzz {

// INVR_FUZZ_VERBOSE=1 prints why each input was rejected (handy when running a target on the
// seed corpus: `INVR_FUZZ_VERBOSE=1 build-fuzz/bin/fuzz_ply tests/fuzz/corpus/fuzz_ply/*`).
inline bool verbose() {
  static const bool v = std::getenv("INVR_FUZZ_VERBOSE") != nullptr;
  return v;
}

inline void rejected(const InputError& e) {
  if (verbose()) std::fprintf(stderr, "rejected: %s\n", e.what());
}

inline void accepted(const std::string& what) {
  if (verbose()) std::fprintf(stderr, "accepted: %s\n", what.c_str());
}

[[noreturn]] inline void violated(const char* condition, const std::string& detail, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: fuzz invariant violated: %s (%s)\n", file, line, condition, detail.c_str());
  std::abort();
}

}  // namespace invr::fuzz

// A promise of the code under test (documented in its header) that the input broke.
#define FUZZ_CHECK(cond, detail)                                         \
  do {                                                                   \
    if (!(cond)) ::invr::fuzz::violated(#cond, (detail), __FILE__, __LINE__); \
  } while (0)
