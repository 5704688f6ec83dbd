// Perfect specular reflection (delta lobe).
#pragma once

#include <optional>

#include "core/bsdf/bsdf_sample.h"

namespace invr::mirror {

inline std::optional<BsdfSample> sample(Rgb reflectance, Vec3 wo) {
  if (wo.z <= 0.f) return std::nullopt;
  return BsdfSample{Vec3(-wo.x, -wo.y, wo.z), reflectance, 1.f, true};
}

}  // namespace invr::mirror
