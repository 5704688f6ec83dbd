// invr-worker: evaluates gradient tasks for an invr-server (see worker.h).
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <atomic>
#include <iostream>

#include "proto/wire/cli_checks.h"
#include "invr_version.h"
#include "worker/worker.h"

namespace {
std::atomic<bool> gStop{false};
void onSignal(int) { gStop = true; }
}  // namespace

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("invr"));  // stdout is for results (and --json)
  CLI::App app{"invr-worker: evaluates mini-batch gradients for an invr-server"};
  app.set_version_flag("--version", "invr-worker " INVR_VERSION);
  invr::worker::WorkerOptions o;
  if (const char* env = std::getenv("INVR_SERVER"); env && *env) o.server = env;
  app.add_option("--server", o.server, "server address host:port (default: $INVR_SERVER, else 127.0.0.1:50051)");
  app.add_option("--threads", o.threads, "render threads (0: every core)")->capture_default_str()->check(invr::wire::kNonNegative);
  app.add_option("--name", o.name, "name shown in the server's log (default host:pid)");
  app.add_option("--max-sessions", o.maxSessions, "per-job sessions kept (least recently used evicted)")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--max-memory-mb", o.maxMemoryMb, "evict sessions while resident memory exceeds this (0: half the RAM)")->capture_default_str()->check(invr::wire::kNonNegative);
  app.add_option("--cache", o.cacheDir, "folder for fetched assets (default: a temporary folder)");
  app.add_option("--drain-seconds", o.drainSeconds,
                 "on SIGTERM, how long the task in hand may take before it is handed back to the server")
      ->capture_default_str()
      ->check(invr::wire::kNonNegative);
  app.add_option("--parent-pid", o.parentPid, "exit when this process exits");
  std::string tlsCa, tlsCert, tlsKey, tlsName, tokenFile;
  app.add_option("--tls-ca", tlsCa, "CA certificate (PEM) that signed the server's: connect over TLS");
  app.add_option("--tls-cert", tlsCert, "client certificate (PEM) for a server that requires one (mutual TLS)");
  app.add_option("--tls-key", tlsKey, "the client certificate's private key (PEM)");
  app.add_option("--tls-server-name", tlsName, "name expected in the server's certificate (default: the host of --server)");
  app.add_option("--token-file", tokenFile, "file holding the server's worker token (default: $INVR_WORKER_TOKEN)");
  CLI11_PARSE(app, argc, argv);
  try {
    o.security = invr::wire::loadClientSecurity(tlsCa, tlsCert, tlsKey, tlsName, tokenFile, "INVR_WORKER_TOKEN");
  } catch (const std::exception& e) {
    std::cerr << "invr-worker: " << e.what() << "\n";
    return 2;
  }
  // SIGTERM: finish (and answer) the task in hand, then leave.
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  try {
    return invr::worker::runWorker(o, gStop);
  } catch (const std::exception& e) {
    std::cerr << "invr-worker: " << e.what() << "\n";
    return 1;
  }
}
