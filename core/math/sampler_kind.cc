// The sampler names of render.sampler and optimization.sampler (rng.h). A file of its own: the
// job parser (and its fuzz target) needs the names without the rest of core/math.
#include "core/error.h"
#include "core/math/rng.h"

namespace invr {

const char* samplerKindName(SamplerKind kind) { return kind == SamplerKind::Sobol ? "sobol" : "independent"; }

SamplerKind samplerKindFromName(const std::string& name, const std::string& field) {
  if (name.empty() || name == "independent") return SamplerKind::Independent;
  if (name == "sobol") return SamplerKind::Sobol;
  throw InputError(field + ": unknown sampler '" + name + "' (expected independent or sobol)");
}

}  // namespace invr
