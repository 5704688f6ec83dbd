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

}  // namespace invr
