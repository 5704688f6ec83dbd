// Local worker processes for the embedded server of `invr run` and `invr-lab bench service`.
#pragma once

#include <signal.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "client/common/exit_codes.h"
#include "client/common/process.h"
#include "client/common/service_client.h"
#include "server/server.h"

namespace invr::cli {

inline std::filesystem::path selfDir() { return std::filesystem::read_symlink("/proc/self/exe").parent_path(); }

// Started with --parent-pid, so they exit with this process even if it is killed.
struct LocalWorkers {
  std::vector<pid_t> pids;
  ~LocalWorkers() { stop(); }
  void start(int n, int threads, int port, const std::filesystem::path& logDir) {
    std::string exe = (selfDir() / "invr-worker").string();
    if (!std::filesystem::exists(exe)) throw ExitError(exit_code::kInternal, "cannot find invr-worker next to this executable (" + exe + ")");
    for (int i = 0; i < n; ++i)
      spawnLogged({exe, "--server", "127.0.0.1:" + std::to_string(port), "--threads", std::to_string(threads), "--parent-pid",
                   std::to_string(getpid()), "--name", "local-" + std::to_string(i + 1)},
                  logDir / ("worker-" + std::to_string(i + 1) + ".log"));
  }
  // `invr-lab bench fake-worker` processes (canned answers, no rendering) for `invr-lab bench service
  // --fake-workers`; each writes its message byte counts to logDir/fake-<i>.stats when it ends.
  void startFake(int n, int port, double seconds, const std::filesystem::path& logDir) {
    std::string exe = (selfDir() / "invr-lab").string();
    for (int i = 0; i < n; ++i) {
      std::string id = std::to_string(i + 1);
      spawnLogged({exe, "bench", "fake-worker", "--server", "127.0.0.1:" + std::to_string(port), "--seconds", std::to_string(seconds),
                   "--name", "fake-" + id, "--stats-file", (logDir / ("fake-" + id + ".stats")).string(), "--parent-pid",
                   std::to_string(getpid())},
                  logDir / ("fake-" + id + ".log"));
    }
  }
  void spawnLogged(std::vector<std::string> args, const std::filesystem::path& logFile) {
    try {
      pids.push_back(spawnProcess(args, logFile, logFile));
    } catch (const std::runtime_error& e) {
      throw ExitError(exit_code::kInternal, e.what());
    }
  }
  void stop() {
    for (pid_t p : pids) kill(p, SIGTERM);
    for (pid_t p : pids) waitProcess(p);
    pids.clear();
  }
};

// A server in this process with its store in `store`, plus local worker processes that have
// all connected (shards stick to the workers present when a job starts).
class EmbeddedService {
 public:
  // httpAddress: the server's dashboard (--http-address), empty for none; finalSpp: samples per
  // pixel of the final renders written with the results (--final-spp).
  EmbeddedService(const std::filesystem::path& store, int workers, int threads, const std::string& httpAddress = "", int finalSpp = 64)
      : server_(options(store, httpAddress, finalSpp)) {
    int port = server_.start();
    local_.start(workers, threads, port, store);
    // Its own loopback server: plaintext, no token, whatever the command line says about others.
    client_ = std::make_unique<ServiceClient>("127.0.0.1:" + std::to_string(port), wire::ClientSecurity{});
    if (!client_->waitForWorkers(workers, 30))
      throw ExitError(exit_code::kInternal, "local workers did not connect (logs in " + store.string() + ")");
  }
  ~EmbeddedService() { stop(); }
  ServiceClient& client() { return *client_; }
  std::string dashboardUrl() const { return server_.dashboardUrl(); }
  void stop() {
    server_.shutdown();  // first: an unfinished job stays as it was, not "worker lost"
    local_.stop();
  }

 private:
  static server::ServerOptions options(const std::filesystem::path& store, const std::string& httpAddress, int finalSpp) {
    server::ServerOptions o;
    o.storeDir = store;
    o.httpAddress = httpAddress;
    o.finalSpp = finalSpp;
    return o;
  }
  server::Server server_;
  LocalWorkers local_;
  std::unique_ptr<ServiceClient> client_;
};

}  // namespace invr::cli
