// Local worker processes for the embedded server of `invr run` and `invr bench service`.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "client/common/exit_codes.h"
#include "client/common/service_client.h"
#include "server/server.h"

extern char** environ;

namespace invr::cli {

inline std::filesystem::path selfDir() { return std::filesystem::read_symlink("/proc/self/exe").parent_path(); }

// Started with --parent-pid, so they exit with this process even if it is killed.
struct LocalWorkers {
  std::vector<pid_t> pids;
  ~LocalWorkers() { stop(); }
  void start(int n, int threads, int port, const std::filesystem::path& logDir) {
    std::string exe = (selfDir() / "invr-worker").string();
    if (!std::filesystem::exists(exe)) throw ExitError(exit_code::kInternal, "cannot find invr-worker next to invr (" + exe + ")");
    for (int i = 0; i < n; ++i)
      spawnLogged({exe, "--server", "127.0.0.1:" + std::to_string(port), "--threads", std::to_string(threads), "--parent-pid",
                   std::to_string(getpid()), "--name", "local-" + std::to_string(i + 1)},
                  logDir / ("worker-" + std::to_string(i + 1) + ".log"));
  }
  // `invr bench fake-worker` processes (canned answers, no rendering) for `invr bench service
  // --fake-workers`; each writes its message byte counts to logDir/fake-<i>.stats when it ends.
  void startFake(int n, int port, double seconds, const std::filesystem::path& logDir) {
    std::string exe = (selfDir() / "invr").string();
    for (int i = 0; i < n; ++i) {
      std::string id = std::to_string(i + 1);
      spawnLogged({exe, "bench", "fake-worker", "--server", "127.0.0.1:" + std::to_string(port), "--seconds", std::to_string(seconds),
                   "--name", "fake-" + id, "--stats-file", (logDir / ("fake-" + id + ".stats")).string(), "--parent-pid",
                   std::to_string(getpid())},
                  logDir / ("fake-" + id + ".log"));
    }
  }
  void spawnLogged(std::vector<std::string> args, const std::filesystem::path& logFile) {
    const std::string exe = args[0];
    {
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      posix_spawn_file_actions_t fa;
      posix_spawn_file_actions_init(&fa);
      std::string log = logFile.string();
      posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      posix_spawn_file_actions_adddup2(&fa, 1, 2);
      // The child must see SIGINT/SIGTERM (this process blocks SIGINT for its own watcher thread).
      posix_spawnattr_t attr;
      posix_spawnattr_init(&attr);
      sigset_t none;
      sigemptyset(&none);
      posix_spawnattr_setsigmask(&attr, &none);
      posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
      pid_t pid = 0;
      int rc = posix_spawn(&pid, exe.c_str(), &fa, &attr, argv.data(), environ);
      posix_spawn_file_actions_destroy(&fa);
      posix_spawnattr_destroy(&attr);
      if (rc != 0) throw ExitError(exit_code::kInternal, "cannot start " + exe + ": " + std::strerror(rc));
      pids.push_back(pid);
    }
  }
  void stop() {
    for (pid_t p : pids) kill(p, SIGTERM);
    for (pid_t p : pids) waitpid(p, nullptr, 0);
    pids.clear();
  }
};

// A server in this process with its store in `store`, plus local worker processes that have
// all connected (shards stick to the workers present when a job starts).
class EmbeddedService {
 public:
  EmbeddedService(const std::filesystem::path& store, int workers, int threads) : server_(options(store)) {
    int port = server_.start();
    local_.start(workers, threads, port, store);
    // Its own loopback server: plaintext, no token, whatever the command line says about others.
    client_ = std::make_unique<ServiceClient>("127.0.0.1:" + std::to_string(port), wire::ClientSecurity{});
    if (!client_->waitForWorkers(workers, 30))
      throw ExitError(exit_code::kInternal, "local workers did not connect (logs in " + store.string() + ")");
  }
  ~EmbeddedService() { stop(); }
  ServiceClient& client() { return *client_; }
  void stop() {
    server_.shutdown();  // first: an unfinished job stays as it was, not "worker lost"
    local_.stop();
  }

 private:
  static server::ServerOptions options(const std::filesystem::path& store) {
    server::ServerOptions o;
    o.storeDir = store;
    return o;
  }
  server::Server server_;
  LocalWorkers local_;
  std::unique_ptr<ServiceClient> client_;
};

}  // namespace invr::cli
