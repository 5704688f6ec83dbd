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

inline constexpr const char* kConvergenceCsvHeader = "method,step,seconds,loss,param_error";

}  // namespace invr
