// Limits on what a user's bytes may declare (image and mesh headers, job fields) and the memory a
// job may take. Every size a file declares is checked here before anything is allocated for it.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>

#include "core/error.h"

namespace invr {

// A limit was exceeded (as opposed to malformed input): the service answers RESOURCE_EXHAUSTED.
class ResourceError : public InputError {
 public:
  using InputError::InputError;
};

// Throws `message` as the same kind of error as `original` (a limit stays a limit when a caller
// adds the field path to it).
[[noreturn]] void rethrowWithMessage(const InputError& original, const std::string& message);

struct InputLimits {
  int maxImageSide = 16384;                     // pixels per side of a texture, target or film
  uint64_t maxMeshVertices = uint64_t(1) << 26; // positions (67 M)
  uint64_t maxMeshTriangles = uint64_t(1) << 26;
  uint32_t maxPolygonVertices = 1024;           // vertices of one PLY face (fan-triangulated)
  uint64_t maxFileBytes = uint64_t(1) << 30;    // a mesh or image file (the asset store's limit too)
  size_t maxStringBytes = 4096;                 // any string in a job (names, paths, patterns)
  size_t maxNameBytes = 256;                    // names: job, shapes, materials, lights, views, parameters
  int maxRepeated = 65536;                      // elements of any repeated field of a job
};

// The process-wide limits (defaults above).
const InputLimits& inputLimits();

// Bytes a job may allocate for its inputs and per-worker state. Charges are made before each
// allocation, so a job over budget fails before it takes the memory.
class MemoryBudget {
 public:
  static constexpr uint64_t kDefaultBytes = uint64_t(2) << 30;  // 2 GiB
  explicit MemoryBudget(uint64_t limitBytes = kDefaultBytes) : limit_(limitBytes) {}
  // Throws ResourceError naming `what` and the limit if the charge does not fit.
  void charge(uint64_t bytes, const std::string& what);
  // Gives back a charge for memory that has been freed again (a parser's working set).
  void release(uint64_t bytes) { used_ -= std::min(bytes, used_); }
  uint64_t used() const { return used_; }
  uint64_t limit() const { return limit_; }

 private:
  uint64_t limit_;
  uint64_t used_ = 0;
};

// "1.5 GiB", "300 MiB", "12 KiB": for messages.
std::string humanBytes(uint64_t bytes);

}  // namespace invr
