#pragma once

namespace invr::exit_code {
inline constexpr int kOk = 0;
inline constexpr int kInputError = 1;  // bad job/scene/mesh/image, reported with the field or file at fault
inline constexpr int kUsage = 2;       // bad command line
}  // namespace invr::exit_code
