// Procedural images so the scene zoo needs no downloaded files.
#pragma once

#include <string>

#include "core/image/image.h"

namespace invr {

struct ProceduralSpec {
  std::string pattern;  // checker | painting | backlit_sky | sun_sky | gradient | bumps
  int width = 64, height = 64;
  Rgb a{0.8f}, b{0.2f};
  uint64_t seed = 0;
};

// Throws InputError for an unknown pattern.
Image makeProceduralImage(const ProceduralSpec& spec);

}  // namespace invr
