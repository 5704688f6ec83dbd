// Helpers for the integration tests: real invr-server and invr-worker processes on loopback,
// ephemeral ports, a temporary folder per test.
#pragma once

#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <condition_variable>
#include <mutex>
#include <set>
#include <numeric>
#include <thread>


#include "core/job/zoo_jobs.h"
#include "core/image/image.h"
#include "core/io/job_io.h"
#include "core/optim/local_run.h"
#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/wire.h"

extern char** environ;

namespace invr::test {

namespace v1 = invr::v1;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

inline const fs::path kBin = INVR_BIN_DIR;

// Time limits a healthy worker must stay under (leases), scaled by INVR_TEST_TIME_SCALE:
// `deploy/test.sh --sanitize` sets 3, where ASan slows every task and heavier tests run beside.
inline int scaledSeconds(int seconds) {
  const char* v = std::getenv("INVR_TEST_TIME_SCALE");
  int scale = v ? std::atoi(v) : 1;
  return seconds * std::max(1, scale);
}

inline pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
  std::vector<std::string> a = args;
  std::vector<char*> argv;
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = 0;
  int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw std::runtime_error(std::string("spawn ") + args[0] + ": " + std::strerror(rc));
  return pid;
}

inline void stopProcess(pid_t& pid, int sig = SIGTERM) {
  if (pid <= 0) return;
  kill(pid, sig);
  waitpid(pid, nullptr, 0);
  pid = 0;
}

// A temporary folder per test.
struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("invr-test-" + std::to_string(getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

class Cluster {
 public:
  explicit Cluster(fs::path dir) : dir_(std::move(dir)) {}
  ~Cluster() {
    for (auto& w : workers_) stopProcess(w, SIGKILL);
    stopProcess(server_, SIGKILL);
  }
  // Starts the server on `port` (0: any) with the store in dir/store; returns its port.
  int startServer(int port = 0, std::vector<std::string> extra = {}) {
    fs::path portFile = dir_ / "port";
    fs::remove(portFile);
    std::vector<std::string> args = {(kBin / "invr-server").string(), "--store", (dir_ / "store").string(), "--address",
                                     "127.0.0.1:" + std::to_string(port), "--port-file", portFile.string()};
    // The final renders of a finished job are written, never judged, by these tests: 4 samples a
    // pixel instead of the default 64 (which was most of each test's time) unless a test asks.
    if (std::find(extra.begin(), extra.end(), "--final-spp") == extra.end()) extra.insert(extra.begin(), {"--final-spp", "4"});
    args.insert(args.end(), extra.begin(), extra.end());
    server_ = spawn(args, dir_ / "server.log");
    for (int i = 0; i < 200 && !fs::exists(portFile); ++i) std::this_thread::sleep_for(50ms);
    std::ifstream in(portFile);
    in >> port_;
    if (port_ <= 0) throw std::runtime_error("server did not start; see " + (dir_ / "server.log").string());
    stub_ = v1::InvrService::NewStub(wire::channel(address()));
    return port_;
  }
  pid_t startWorker(int threads = 1, std::vector<std::string> extra = {}) {
    std::vector<std::string> args = {(kBin / "invr-worker").string(), "--server", address(), "--threads", std::to_string(threads),
                                     "--name", "w" + std::to_string(workers_.size() + 1)};
    args.insert(args.end(), extra.begin(), extra.end());
    pid_t p = spawn(args, workerLog(workers_.size()));
    workers_.push_back(p);
    // Shards stick to the workers present when a job starts: wait until this one is connected.
    for (int i = 0; i < 400; ++i) {
      grpc::ClientContext ctx;
      v1::ListWorkersResponse r;
      if (stub_->ListWorkers(&ctx, v1::ListWorkersRequest(), &r).ok() && r.workers_size() >= int(workers_.size())) break;
      std::this_thread::sleep_for(25ms);
    }
    return p;
  }
  void killServer() { stopProcess(server_, SIGKILL); }
  fs::path workerLog(size_t i) const { return dir_ / ("worker" + std::to_string(i + 1) + ".log"); }
  void killWorker(size_t i) { stopProcess(workers_.at(i), SIGKILL); }
  // SIGTERM; returns the worker's exit status.
  int terminateWorker(size_t i) {
    int status = -1;
    kill(workers_.at(i), SIGTERM);
    waitpid(workers_.at(i), &status, 0);
    workers_.at(i) = 0;
    return status;
  }
  std::string upload(const std::string& bytes) {
    grpc::ClientContext ctx;
    v1::AssetInfo info;
    auto w = stub_->UploadAsset(&ctx, &info);
    v1::AssetChunk ch;
    ch.set_data(bytes);
    w->Write(ch);
    w->WritesDone();
    EXPECT_TRUE(w->Finish().ok());
    return info.sha256();
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  v1::InvrService::Stub& stub() { return *stub_; }
  fs::path store() const { return dir_ / "store"; }

  grpc::Status submit(const v1::JobSpec& job, std::string* id, const std::string& requestId = "") {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 60s);
    v1::SubmitJobRequest req;
    req.set_request_id(requestId);
    *req.mutable_spec() = job;
    v1::SubmitJobResponse resp;
    grpc::Status st = stub_->SubmitJob(&ctx, req, &resp);
    if (id) *id = resp.job_id();
    return st;
  }
  // Events from `from` until the final one (or until stopAfter returns true).
  std::vector<v1::ProgressEvent> watch(const std::string& id, uint64_t from = 0,
                                       const std::function<bool(const v1::ProgressEvent&)>& stopAfter = {}) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 600s);
    v1::WatchJobRequest req;
    req.set_job_id(id);
    req.set_from_sequence(from);
    auto r = stub_->WatchJob(&ctx, req);
    std::vector<v1::ProgressEvent> out;
    v1::ProgressEvent e;
    while (r->Read(&e)) {
      out.push_back(e);
      if (stopAfter && stopAfter(e)) {
        ctx.TryCancel();
        break;
      }
    }
    r->Finish();
    return out;
  }
  v1::JobStatus get(const std::string& id) {
    grpc::ClientContext ctx;
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::JobStatus s;
    EXPECT_TRUE(stub_->GetJob(&ctx, req, &s).ok());
    return s;
  }
  std::vector<float> checkpointTheta(const std::string& id) {
    std::ifstream in(store() / "jobs" / id / "checkpoint.pb", std::ios::binary);
    v1::Checkpoint ck;
    EXPECT_TRUE(in && ck.ParseFromIstream(&in));
    return {ck.theta().begin(), ck.theta().end()};
  }

 private:
  fs::path dir_;
  pid_t server_ = 0;
  std::vector<pid_t> workers_;
  int port_ = 0;
  std::unique_ptr<v1::InvrService::Stub> stub_;
};

inline v1::JobSpec smallJob(const std::string& scene, int steps) {
  v1::JobSpec j = zooJob(scene);
  auto* o = j.mutable_optimization();
  o->set_steps(steps);
  o->set_target_spp(4);
  o->mutable_restir()->set_burn_in(2);
  return j;
}

inline std::vector<float> inProcess(const v1::JobSpec& job) {
  Problem p = buildProblem(job);
  return runLocally(p).theta;
}

inline std::vector<uint64_t> stepsOf(const std::vector<v1::ProgressEvent>& evs) {
  std::vector<uint64_t> s;
  for (const auto& e : evs)
    if (e.has_step()) s.push_back(e.step().step());
  return s;
}

inline bool anyMessage(const std::vector<v1::ProgressEvent>& evs, const std::string& needle) {
  for (const auto& e : evs)
    if (e.has_message() && e.message().find(needle) != std::string::npos) return true;
  return false;
}

}  // namespace invr::test
