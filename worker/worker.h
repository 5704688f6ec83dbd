// invr-worker: dials the server, keeps a session per (job, shard) — scene and BVH, targets,
// gradient engine and ReSTIR reservoir chains — and evaluates the tasks it is sent.
#pragma once

#include <atomic>
#include <filesystem>
#include <string>

#include "proto/wire/security.h"

namespace invr::worker {

struct WorkerOptions {
  std::string server = "127.0.0.1:50051";
  int threads = 0;               // 0: every core
  std::string name;              // default host:pid
  size_t maxSessions = 16;       // least recently used sessions beyond this are evicted
  double maxMemoryMb = 0;        // ... and while the process holds more than this (0: half the RAM)
  std::filesystem::path cacheDir;  // fetched assets; default: a temporary folder
  int parentPid = 0;             // exit when this process is gone (local workers of `invr run`)
  double heartbeatSeconds = 1.0;
  // On SIGTERM the task in hand gets this long to finish before it is handed back (keep it below
  // the orchestrator's grace period, e.g. Kubernetes' terminationGracePeriodSeconds).
  double drainSeconds = 20;
  invr::wire::ClientSecurity security;  // TLS and the worker token
};

// Exit code when the server refuses the worker's credentials (UNAUTHENTICATED, PERMISSION_DENIED).
inline constexpr int kExitRefused = 3;

// Serves until `stop` becomes true (SIGTERM): the task in hand is finished and answered first.
// Reconnects with back-off when the server goes away. Returns the process exit code.
int runWorker(const WorkerOptions& options, const std::atomic<bool>& stop);

}  // namespace invr::worker
