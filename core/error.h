// User-facing errors: the message names the file or field at fault. Everything a user can get
// wrong (job JSON, meshes, images, names, numbers) is reported through this type.
#pragma once

#include <stdexcept>
#include <string>

namespace invr {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Thrown by long computations (renders, gradient evaluations) whose cancellation flag was raised.
struct EvaluationCancelled {};

// Internal invariants (slot coverage, capacities, distribution bounds), checked in debug and
// sanitizer builds (INVR_CHECKS) and compiled out of release builds, where they sit on hot paths.
// A failure is a bug in invr, never a user's mistake: std::logic_error naming the place.
#ifdef INVR_CHECKS
#define INVR_INVARIANT(cond, what)                                                                                  \
  do {                                                                                                             \
    if (!(cond)) throw std::logic_error(std::string(__FILE__) + ":" + std::to_string(__LINE__) + ": invariant: " + (what)); \
  } while (0)
#else
// Unevaluated (sizeof), but it still counts as a use of what the condition names.
#define INVR_INVARIANT(cond, what) \
  do {                             \
    (void)sizeof(!(cond));         \
  } while (0)
#endif

}  // namespace invr
