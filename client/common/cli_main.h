// What `invr` and `invr-lab` share around their commands: parsing, an unknown command named with
// the closest ones, and the mapping of errors to exit codes (client/common/exit_codes.h).
#pragma once

#include <CLI/CLI.hpp>

namespace invr::cli {

// Parses argv into `app` (whose subcommands are registered) and runs the chosen one. Returns the
// process's exit status: `exitCode` as the command set it, or the code of the error that ended it.
// `program` prefixes every message ("invr: error: ...").
int runCommandLine(CLI::App& app, int argc, char** argv, const char* program, const int& exitCode);

}  // namespace invr::cli
