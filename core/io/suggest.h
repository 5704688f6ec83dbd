// The names a user probably meant, for "unknown name" errors (fields, enum values, parameters,
// commands): "render.spq: unknown field; did you mean 'spp'?".
#pragma once

#include <string>
#include <vector>

namespace invr {

// Up to `max` known names close to `given` (edit distance, case-insensitive, at most a third of
// the name's length; or one name containing the other), closest first.
std::vector<std::string> closestNames(const std::string& given, const std::vector<std::string>& known, size_t max = 3);

// "; did you mean 'a' or 'b'?", or "" when nothing is close.
std::string didYouMean(const std::string& given, const std::vector<std::string>& known);

}  // namespace invr
