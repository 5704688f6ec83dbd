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

// Derivatives of a BSDF value (times |cos|) with respect to its parameters: per channel c,
// d eval_c / d albedo_c (the albedo enters each channel alone) and d eval_c / d alpha.
struct BsdfDerivatives {
  Rgb dAlbedo{0.f};
  Rgb dAlpha{0.f};
};

// A sampling density and its derivatives with respect to the BSDF's parameters: d pdf / d alpha,
// and d pdf / d albedo_c per channel (rough plastic's lobe choice depends on the albedo).
struct PdfDerivatives {
  float pdf = 0.f;
  float dAlpha = 0.f;
  Rgb dAlbedo{0.f};
};

}  // namespace invr
