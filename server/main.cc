// invr-server: the optimisation service (see server.h).
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <fstream>
#include <iostream>

#include "proto/wire/cli_checks.h"
#include "invr_version.h"
#include "proto/wire/security.h"
#include "server/server.h"

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("invr"));  // stdout is for results (and --json)
  CLI::App app{"invr-server: accepts optimisation jobs and farms their gradient steps to invr-worker processes"};
  app.set_version_flag("--version", "invr-server " INVR_VERSION);
  invr::server::ServerOptions o;
  o.address = "127.0.0.1:50051";  // the address every client and worker tries by default
  std::string portFile;
  double maxAssetMb = 1024, maxJobMb = 2048;
  app.add_option("--store", o.storeDir, "job and asset store folder (kept across restarts)")->capture_default_str();
  app.add_option("--address", o.address, "listen address (a port in use is an error naming it; port 0 picks a free one)")->capture_default_str();
  app.add_option("--port-file", portFile, "write the port listened on to this file");
  app.add_option("--max-queued", o.maxQueued, "jobs waiting beyond this are refused (RESOURCE_EXHAUSTED)")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--max-running-jobs", o.maxRunningJobs, "jobs that run at once, sharing the workers by priority; more wait in the queue")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  app.add_option("--lease-seconds", o.leaseSeconds, "a task unanswered this long is reassigned")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--heartbeat-timeout", o.heartbeatTimeoutSeconds, "a worker silent this long is presumed gone")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--max-attempts", o.maxAttempts, "attempts per shard and step before a job fails")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--final-spp", o.finalSpp, "samples per pixel of the final renders written with a job's results")
      ->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--final-views", o.finalViews, "final renders are written for the first this many views (0: none)")
      ->capture_default_str()->check(invr::wire::kNonNegative);
  app.add_option("--assign-grace", o.assignGraceSeconds, "at a job's start, seconds to wait for one worker per shard")->capture_default_str()->check(invr::wire::kNonNegative);
  app.add_option("--max-asset-mb", maxAssetMb, "largest upload accepted")->capture_default_str()->check(invr::wire::kPositive);
  app.add_option("--max-job-memory-mb", maxJobMb,
                 "memory one job may take (textures, meshes, targets and per-worker state); larger jobs are refused (RESOURCE_EXHAUSTED)")
      ->capture_default_str()
      ->check(invr::wire::kPositive);
  app.add_option("--metrics-address", o.metricsAddress, "serve Prometheus metrics at http://HOST:PORT/metrics (default: none)");
  app.add_option("--http-address", o.httpAddress,
                 "serve the dashboard, a read-only web application and its JSON API, at HOST:PORT (a port alone: 127.0.0.1; "
                 "https when --tls-cert/--tls-key are given; beyond loopback it needs them and client tokens, or --insecure; "
                 "default: none)");
  app.add_option("--health-address", o.healthAddress,
                 "also serve the gRPC health service alone, in plaintext, on HOST:PORT (for probes that cannot do TLS)");
  std::string tlsCert, tlsKey, tlsClientCa, clientTokenFile, workerTokenFile;
  app.add_option("--tls-cert", tlsCert, "server certificate chain (PEM): serve TLS; needed to listen beyond loopback (or --insecure)");
  app.add_option("--tls-key", tlsKey, "the certificate's private key (PEM)");
  app.add_option("--tls-client-ca", tlsClientCa, "CA (PEM) whose certificates clients and workers must present (mutual TLS)");
  app.add_flag("--insecure", o.insecure, "allow plaintext on a non-loopback address (logs a warning)");
  app.add_option("--client-token-file", clientTokenFile,
                 "bearer tokens clients may send, one per line: 'NAME TOKEN' or the token alone (named client; one such line); the "
                 "name is shown as who submitted a job (default: $INVR_CLIENT_TOKEN; none: client API and dashboard unchecked)");
  app.add_option("--worker-token-file", workerTokenFile,
                 "bearer token workers must send, different from the client token (default: $INVR_WORKER_TOKEN; none: worker API unchecked)");
  CLI11_PARSE(app, argc, argv);
  auto tokenFrom = [](const std::string& file, const char* env, const char* what) -> std::string {
    if (!file.empty()) return invr::wire::readTokenFile(file, what);
    const char* v = std::getenv(env);
    return v ? std::string(v) : std::string();
  };
  try {
    if (!tlsCert.empty()) o.tlsCertPem = invr::wire::readPemFile(tlsCert, "--tls-cert");
    if (!tlsKey.empty()) o.tlsKeyPem = invr::wire::readPemFile(tlsKey, "--tls-key");
    if (!tlsClientCa.empty()) o.tlsClientCaPem = invr::wire::readPemFile(tlsClientCa, "--tls-client-ca");
    if (!clientTokenFile.empty())
      o.clientTokens = invr::server::readClientTokenFile(clientTokenFile);
    else
      o.clientToken = tokenFrom("", "INVR_CLIENT_TOKEN", "--client-token-file");
    o.workerToken = tokenFrom(workerTokenFile, "INVR_WORKER_TOKEN", "--worker-token-file");
  } catch (const std::exception& e) {
    std::cerr << "invr-server: " << e.what() << "\n";
    return 2;
  }
  o.maxAssetBytes = uint64_t(maxAssetMb * 1024 * 1024);
  o.maxJobBytes = uint64_t(maxJobMb * 1024 * 1024);

  // Signals are taken by a waiting thread, so shutdown runs outside a signal handler.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  try {
    invr::server::Server server(o);
    int port = server.start();
    if (!portFile.empty()) {
      std::ofstream(portFile + ".tmp") << port << "\n";
      std::rename((portFile + ".tmp").c_str(), portFile.c_str());
    }
    std::cout << "invr-server: listening on port " << port << std::endl;
    if (const std::string url = server.dashboardUrl(); !url.empty()) std::cout << "invr-server: dashboard at " << url << std::endl;
    int sig = 0;
    sigwait(&set, &sig);
    spdlog::info("signal {}: shutting down (unfinished jobs resume on restart)", sig);
    server.shutdown();
  } catch (const std::exception& e) {
    std::cerr << "invr-server: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
