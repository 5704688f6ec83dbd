// Command-line number checks that say what is wrong as a person would ("must be a positive
// number (got 0)"), where CLI11's own print the range's limits as 300-digit doubles.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <string>

namespace invr::wire {

namespace detail {
inline CLI::Validator numberCheck(const char* name, bool (*ok)(double), const char* rule) {
  return CLI::Validator(
      [ok, rule](std::string& in) -> std::string {
        double v = 0;
        size_t used = 0;
        try {
          v = std::stod(in, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used != in.size() || in.empty() || !std::isfinite(v)) return "expected a number, got '" + in + "'";
        if (!ok(v)) return std::string("must be ") + rule + " (got " + in + ")";
        return {};
      },
      name);
}
}  // namespace detail

inline const CLI::Validator kPositive = detail::numberCheck("POSITIVE", [](double v) { return v > 0; }, "a positive number");
inline const CLI::Validator kNonNegative = detail::numberCheck("NONNEGATIVE", [](double v) { return v >= 0; }, "zero or more");

}  // namespace invr::wire
