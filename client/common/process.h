// Child processes of the client: local workers of the embedded server, the charting script.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace invr::cli {

// Starts args[0] (a path) with `args`, its standard output written to `out` and its standard error
// to `err` (the same file when they are equal), with no signal blocked (this process blocks SIGINT
// for its own watcher thread; a child must still see it). Throws std::runtime_error when it cannot
// be started.
pid_t spawnProcess(const std::vector<std::string>& args, const std::filesystem::path& out, const std::filesystem::path& err);

// Waits for the child; its exit code, or -1 when it did not exit normally.
int waitProcess(pid_t pid);

}  // namespace invr::cli
