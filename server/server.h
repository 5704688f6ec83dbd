// invr-server: accepts optimisation jobs from clients, farms each step's shards of views to the
// workers that dialled in (sticky, leased), applies the optimiser, checkpoints and reports progress.
// Several jobs run at once and share the workers.
//
// Parts: ClientService and WorkerService (gRPC callbacks), Admission (validation, plan, memory),
// JobBook (records, events, queue, watchers), Scheduler (workers, leases, fair share) and
// JobRunner (one job's step loop), over JobStore and AssetStore.
//
// Threads: gRPC's callback threads only move messages and touch in-memory state; job validation
// runs on a control thread and each running job's step loop on a runner thread, so no rendering
// or disk-heavy work ever happens inside a callback.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "server/auth.h"

namespace invr::server {

struct ServerOptions {
  std::filesystem::path storeDir = "invr-store";
  std::string address = "127.0.0.1:0";  // loopback unless told otherwise; port 0 picks one
  int maxQueued = 16;                    // queued jobs beyond this: RESOURCE_EXHAUSTED
  int maxRunningJobs = 4;                // jobs running at once, sharing the workers (fair share by priority)
  double leaseSeconds = 600;             // a task not answered by then is reassigned
  double heartbeatTimeoutSeconds = 10;   // a silent worker is presumed gone
  int maxAttempts = 3;                   // per shard and step, before the job fails
  double assignGraceSeconds = 3;         // at a job's start, wait this long for one worker per shard
  uint64_t maxAssetBytes = uint64_t(1) << 30;
  // Memory one job may take: its textures, meshes and targets as the server validates them, plus
  // the per-worker state of `invr plan`'s model. Beyond it: RESOURCE_EXHAUSTED at submission.
  uint64_t maxJobBytes = uint64_t(2) << 30;
  // Transport security. A non-loopback address needs TLS (certificate and key, PEM) or `insecure`.
  std::string tlsCertPem, tlsKeyPem;
  std::string tlsClientCaPem;  // non-empty: clients and workers must present a certificate it signed (mutual TLS)
  bool insecure = false;       // allow plaintext beyond loopback (a warning is logged)
  // Bearer tokens; none: that API is not checked. Client and worker tokens must differ.
  std::string clientToken, workerToken;  // clientToken: one client token, named "client"
  std::vector<NamedToken> clientTokens;  // more client tokens, by name (`--client-token-file`)
  // host:port of the dashboard (a read-only web application over HTTP, HTTPS with the TLS
  // certificate; empty: none). Beyond loopback it needs TLS or `insecure`, as the gRPC port.
  std::string httpAddress;
  std::string metricsAddress;  // host:port for Prometheus metrics at /metrics over HTTP (empty: none)
  std::string healthAddress;   // host:port of a plaintext listener with only the gRPC health service (probes that cannot do TLS)
  int finalSpp = 64;                     // final renders written with the results
  int finalViews = 4;                    // ... for the first this many views
};

class Server {
 public:
  explicit Server(ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Loads the job store (unfinished jobs are queued again), starts listening; returns the port.
  int start();
  // Stops accepting calls, ends streams, joins threads. Unfinished jobs stay in the store.
  void shutdown();
  void wait();
  int metricsPort() const;  // 0 without a metrics endpoint
  int healthPort() const;   // 0 without a health listener
  std::string dashboardUrl() const;  // empty without --http-address

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace invr::server
