// Writing an optimisation's results: parameters as JSON (textures also as EXR images a person can
// look at) and the convergence CSV. Shared by `invr optimize` and the server.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/diff/parameters.h"

namespace invr {

// Writes dir/parameters.json and dir/<name>.exr per texture parameter; returns the files written.
std::vector<std::string> writeParameters(const std::filesystem::path& dir, const ParameterRegistry& params,
                                         const std::vector<float>& theta);

// Jobs with sampling parameters (docs/variance.md): the light-selection probabilities they reached.
// dir/light_selection.csv (light,probability) holds the global rule; each view with per-pixel logits
// gets dir/selection_view<v>.exr, one channel per light (named after it) per cell of its map.
// Writes theta into `scene`; returns the files written (none without sampling parameters).
class Scene;
std::vector<std::string> writeSelectionResults(const std::filesystem::path& dir, const ParameterRegistry& params, Scene& scene,
                                               const std::vector<float>& theta);

inline constexpr const char* kConvergenceCsvHeader = "method,step,seconds,loss,param_error";

}  // namespace invr
