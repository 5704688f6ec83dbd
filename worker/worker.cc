// invr-worker's wiring: the connection (connection.h) hands tasks to the task runner
// (task_runner.h), which keeps its state in the session cache (sessions.h) and fetches assets
// through the asset cache (asset_cache.h); this file reconnects with back-off.
#include "worker/worker.h"

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <thread>

#include "worker/asset_cache.h"
#include "worker/connection.h"
#include "worker/sessions.h"
#include "worker/task_runner.h"

namespace invr::worker {

namespace {

namespace v1 = invr::v1;

int serve(WorkerOptions o, const std::atomic<bool>& stop) {
  if (o.name.empty()) {
    char host[256] = {0};
    gethostname(host, sizeof host - 1);
    o.name = std::string(host) + ":" + std::to_string(getpid());
  }
  if (o.cacheDir.empty()) o.cacheDir = std::filesystem::temp_directory_path() / ("invr-worker-" + std::to_string(getpid()));
  std::filesystem::create_directories(o.cacheDir);
  const double memoryLimitMb =
      o.maxMemoryMb > 0 ? o.maxMemoryMb : 0.5 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE)) / 1048576.0;
  auto shouldStop = [&] { return stop.load() || (o.parentPid && getppid() != o.parentPid); };
  std::atomic<bool> cancel{false};
  AssetCache assets(o.cacheDir, o.server, o.security);
  SessionCache sessions(o.maxSessions, memoryLimitMb, o.name);
  SpecCache specs;
  TaskRunner runner(sessions, specs, assets, cancel, o.name);
  Connection connection(o, cancel, shouldStop);
  const Connection::Handlers handlers{[&](const v1::Task& t) { return runner.execute(t); },
                                      [&](const std::string& job) {
                                        sessions.release(job);
                                        specs.release(job);
                                      }};
  auto removeCache = [&] {
    std::error_code ec;
    std::filesystem::remove_all(o.cacheDir, ec);
  };
  double backoff = 0.1;
  bool warnedUnreachable = false;
  while (!shouldStop()) {
    const bool served = connection.serve(handlers);
    if (shouldStop()) break;
    if (!connection.refusal().ok()) {  // wrong credentials do not fix themselves: say so and stop
      const grpc::Status& r = connection.refusal();
      spdlog::error("worker {}: the server refused this worker: {} ({}); check --token-file / $INVR_WORKER_TOKEN and the TLS options", o.name,
                    r.error_message(), r.error_code() == grpc::StatusCode::PERMISSION_DENIED ? "PERMISSION_DENIED" : "UNAUTHENTICATED");
      removeCache();
      return kExitRefused;
    }
    if (served) {
      backoff = 0.1;
      warnedUnreachable = false;
    } else if (!warnedUnreachable) {  // a worker started before its server (or a wrong --server) says so once
      spdlog::warn("worker {}: cannot reach the server at {}; retrying (every 2 s at most) until it answers", o.name, o.server);
      warnedUnreachable = true;
    }
    // The server went away (or never answered): sessions may belong to a server that no longer
    // exists, so drop them; a reassigned shard is rebuilt with a burn-in.
    sessions.clear();
    specs.clear();
    std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
    backoff = std::min(backoff * 2, 2.0);
  }
  removeCache();
  spdlog::info("worker {}: stopped", o.name);
  return 0;
}

}  // namespace

int runWorker(const WorkerOptions& options, const std::atomic<bool>& stop) {
  std::unique_ptr<tbb::global_control> threads;
  if (options.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(options.threads));
  return serve(options, stop);
}

}  // namespace invr::worker
