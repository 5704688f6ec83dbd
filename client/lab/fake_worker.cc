// invr-lab bench fake-worker: a worker that renders nothing. It speaks the worker protocol (hello,
// heartbeats, results) and answers each task after `--seconds` with canned data of the job's
// size: a zero gradient as long as θ, or black final images of the film's size. `invr-lab bench
// service --fake-workers N` starts N of them to measure the server's own cost per step with many
// workers, without the machine's cores going to rendering.
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>

#include "proto/wire/cli_checks.h"
#include "client/lab/lab_commands.h"
#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/wire.h"

namespace invr::cli {

namespace v1 = invr::v1;

namespace {

struct FakeWorkerArgs {
  std::string server = "127.0.0.1:50051", name = "fake", statsFile;
  double seconds = 0.05;
  int parentPid = 0;
};

int runFakeWorker(const FakeWorkerArgs& a) {
  auto stub = v1::WorkerService::NewStub(wire::channel(a.server));
  grpc::ClientContext ctx;
  auto stream = stub->Connect(&ctx);
  std::mutex wmu;
  uint64_t bytesIn = 0, resultBytes = 0, tasks = 0;
  auto write = [&](const v1::WorkerMessage& m) {
    std::lock_guard<std::mutex> lk(wmu);

    return stream->Write(m);
  };
  v1::WorkerMessage hello;
  hello.mutable_hello()->set_name(a.name);
  hello.mutable_hello()->set_capacity(1);
  if (!write(hello)) return 5;
  std::atomic<bool> done{false};
  std::thread heart([&] {
    while (!done) {
      for (int i = 0; i < 10 && !done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (a.parentPid && getppid() != a.parentPid) ctx.TryCancel();
      v1::WorkerMessage hb;
      hb.mutable_heartbeat();
      if (!done) write(hb);
    }
  });
  std::map<std::string, std::pair<int, int>> film;  // job -> film size, from its spec
  v1::ServerMessage m;
  while (stream->Read(&m)) {
    if (!m.has_task()) continue;
    const v1::Task& t = m.task();
    if (t.kind() == v1::Task::GRADIENT && !t.render_only()) {  // the per-step traffic; not burn-in, not final renders
      bytesIn += m.ByteSizeLong();
      ++tasks;
    }
    v1::WorkerMessage out;
    v1::TaskResult* r = out.mutable_result();
    r->set_task_id(t.task_id());
    r->set_job_id(t.job_id());
    r->set_shard(t.shard());
    if (t.has_spec()) {
      int w = t.spec().scene().film().width() ? t.spec().scene().film().width() : 256;
      film[t.job_id()] = {w, t.spec().scene().film().height() ? t.spec().scene().film().height() : w};
    }
    auto f = film.find(t.job_id());
    if (f == film.end()) {
      r->set_spec_unknown(true);
      write(out);
      continue;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(a.seconds));
    if (t.kind() == v1::Task::FINAL_RENDER || t.kind() == v1::Task::SNAPSHOT) {
      for (int k = 0; k < (t.kind() == v1::Task::SNAPSHOT ? 1 : 2) * t.views_size(); ++k) {
        v1::FloatImage* im = r->add_renders();
        im->set_width(f->second.first);
        im->set_height(f->second.second);
        im->set_channels(3);
        im->mutable_pixels()->Resize(f->second.first * f->second.second * 3, 0.f);
      }
    } else {
      r->mutable_gradient()->Resize(t.theta_size(), 0.f);
      r->mutable_stats()->set_loss(1.0);
    }
    r->mutable_stats()->set_seconds_primal(a.seconds);
    if (t.kind() == v1::Task::GRADIENT && !t.render_only()) resultBytes += out.ByteSizeLong();
    write(out);
  }
  done = true;
  heart.join();
  stream->Finish();
  if (!a.statsFile.empty()) std::ofstream(a.statsFile) << tasks << " " << bytesIn << " " << resultBytes << "\n";
  return 0;
}

}  // namespace

void addBenchFakeWorkerCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<FakeWorkerArgs>();
  auto* c = bench.add_subcommand("fake-worker",
                                 "A worker that renders nothing: canned answers of the job's size after --seconds (for bench service "
                                 "--fake-workers)");
  c->group("");  // a tool of the benchmark, not a command users need
  c->add_option("--server", a->server)->capture_default_str();
  c->add_option("--seconds", a->seconds, "simulated compute per task")->capture_default_str()->check(invr::wire::kNonNegative);
  c->add_option("--name", a->name)->capture_default_str();
  c->add_option("--stats-file", a->statsFile, "write 'tasks task_bytes result_bytes' of its gradient tasks here at the end");
  c->add_option("--parent-pid", a->parentPid, "exit when this process exits");
  c->callback([a, &exitCode] { exitCode = runFakeWorker(*a); });
}

}  // namespace invr::cli
