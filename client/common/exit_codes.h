#pragma once

#include <stdexcept>
#include <string>

namespace invr::exit_code {
inline constexpr int kOk = 0;
inline constexpr int kInputError = 1;         // bad job/scene/mesh/image, reported with the field or file at fault
inline constexpr int kUsage = 2;              // bad command line
inline constexpr int kInternal = 3;           // a bug: please report
inline constexpr int kJobFailed = 4;          // the job ran and failed (diverged, workers kept failing, ...)
inline constexpr int kServerUnavailable = 5;  // no server at the address (or it went away)
inline constexpr int kCancelled = 6;          // the job was cancelled
inline constexpr int kRefused = 7;            // the server refused the credentials (token or TLS certificate)
inline constexpr int kInterrupted = 130;      // Ctrl-C while watching: the job itself goes on
}  // namespace invr::exit_code

namespace invr::cli {

// An error that ends the command with a specific exit code (main prints the message).
struct ExitError : std::runtime_error {
  ExitError(int code, const std::string& message) : std::runtime_error(message), code(code) {}
  int code;
};

}  // namespace invr::cli
