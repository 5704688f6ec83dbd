#pragma once

#include "core/math/vec.h"

namespace invr {

// A sampled incident direction. weight = f * |cos| / pdf (for delta lobes: the lobe's weight
// including the discrete choice). pdf is a solid-angle density, or the discrete probability of the
// chosen delta lobe when delta is set.
struct BsdfSample {
  Vec3 wi;
  Rgb weight;
  float pdf = 0.f;
  bool delta = false;
  bool transmitted = false;
};

}  // namespace invr
