// invr-lab bench service: what the service costs and what a second worker buys.
//   overhead_one_worker: per-step time of a job on the service with one worker, against the same
//     job in process through the GradientEngine (same threads), minus 1. Target <= 0.05.
//   speedup_two_workers: steps/s with two single-threaded workers over one, on a compute-bound
//     job whose views split into two shards. Target >= 1.6 on two cores.
//   concurrent_throughput_ratio: two jobs submitted together to two single-threaded workers,
//     against the same two jobs back to back on the same workers: (back-to-back wall time) /
//     (together wall time). Target >= 0.9.
//   concurrent_share_first: in the together run, the first job's share of the two jobs' worker
//     time (JobStatus.worker_seconds); the jobs are alike, priorities equal. Target 0.5 +- 0.1.
// Steady-state rates: the first step (session build: scene, BVH, targets) is excluded.
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <sys/resource.h>

#include <algorithm>
#include <fstream>
#include <chrono>
#include <iostream>
#include <thread>

#include "proto/wire/cli_checks.h"
#include "client/common/bench_report.h"
#include "client/lab/lab_commands.h"
#include "client/common/embedded.h"
#include "client/common/service_client.h"
#include "core/job/zoo_jobs.h"
#include "core/scene/zoo.h"
#include "core/optim/local_run.h"
#include "server/server.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace v1 = invr::v1;

namespace {

struct BenchServiceArgs {
  int steps = 12;
  int repeats = 2;
  bool json = false;
  int fakeWorkers = 0;
  double fakeSeconds = 0.25;
};

// Median seconds per step after the first (robust to another tenant's burst on a shared machine),
// from a list of (step, seconds since start).
double steadySecondsPerStep(const std::vector<std::pair<uint64_t, double>>& pts) {
  if (pts.size() < 3) throw std::runtime_error("bench service: too few steps to time");
  std::vector<double> d;
  for (size_t i = 1; i < pts.size(); ++i) d.push_back((pts[i].second - pts[i - 1].second) / double(pts[i].first - pts[i - 1].first));
  std::nth_element(d.begin(), d.begin() + long(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// Time per step the service itself spends (transport + optimiser update + checkpoint), as a
// fraction of the step, averaged over the steps after the first. Filled by serviceSecondsPerStep.
double gAccountedOverhead = 0;

double serviceSecondsPerStep(const v1::JobSpec& job, int workers, int threads) {
  auto store = std::filesystem::temp_directory_path() / ("invr-bench-" + std::to_string(getpid()));
  std::filesystem::remove_all(store);
  EmbeddedService service(store, workers, threads);
  ServiceClient& c = service.client();
  auto r = c.submit(job, "");
  std::vector<std::pair<uint64_t, double>> pts;
  std::atomic<bool> never{false};
  double own = 0, total = 0;
  auto final = c.watch(r.job_id(), 0, [&](const v1::ProgressEvent& e) {
    if (!e.has_step()) return;
    if (!pts.empty()) {
      own += e.step().transport_seconds() + e.step().update_seconds();
      total += e.step().seconds() - pts.back().second;
    }
    pts.emplace_back(e.step().step(), e.step().seconds());
  }, never);
  gAccountedOverhead = own / std::max(total, 1e-9);
  service.stop();
  std::filesystem::remove_all(store);
  if (!final || final->state() != v1::SUCCEEDED) throw std::runtime_error("bench service: job did not succeed: " + (final ? final->reason() : ""));
  return steadySecondsPerStep(pts);
}

double inProcessSecondsPerStep(const v1::JobSpec& job, int threads) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  Problem p = buildProblem(job);
  std::vector<std::pair<uint64_t, double>> pts;
  runLocally(p, [&](const StepReport& r) { pts.emplace_back(r.step, r.seconds); });
  return steadySecondsPerStep(pts);
}

// Wall seconds to run `jobs` on one embedded service with two single-threaded workers, either all
// submitted at once or each after the previous ended; the jobs' worker seconds in `workerSeconds`.
double twoJobsSeconds(const std::vector<v1::JobSpec>& jobs, bool together, std::vector<double>& workerSeconds) {
  auto store = std::filesystem::temp_directory_path() / ("invr-bench-two-" + std::to_string(getpid()));
  std::filesystem::remove_all(store);
  EmbeddedService service(store, 2, 1);
  ServiceClient& c = service.client();
  std::atomic<bool> never{false};
  std::vector<std::string> ids;
  auto waitFor = [&](const std::string& id) {
    auto final = c.watch(id, 0, [](const v1::ProgressEvent&) {}, never);
    if (!final || final->state() != v1::SUCCEEDED) throw std::runtime_error("bench service: job did not succeed: " + (final ? final->reason() : ""));
  };
  const Stopwatch clock;
  for (const auto& j : jobs) {
    ids.push_back(c.submit(j, "").job_id());
    if (!together) waitFor(ids.back());
  }
  for (const auto& id : ids) waitFor(id);
  double wall = clock.seconds();
  workerSeconds.clear();
  for (const auto& id : ids) workerSeconds.push_back(c.get(id).worker_seconds());
  service.stop();
  std::filesystem::remove_all(store);
  return wall;
}

double residentMb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// The server alone (in this process) with N fake workers in processes of their own: its CPU time
// per step against the step's wall time, its memory across the job, and the bytes that travel.
void runFake(const BenchServiceArgs& a) {
  spdlog::set_level(spdlog::level::err);
  const int n = a.fakeWorkers;
  auto store = std::filesystem::temp_directory_path() / ("invr-bench-fake-" + std::to_string(getpid()));
  std::filesystem::remove_all(store);
  std::filesystem::create_directories(store);
  server::ServerOptions o;
  o.storeDir = store / "store";
  o.assignGraceSeconds = 30;
  auto srv = std::make_unique<server::Server>(o);
  int port = srv->start();
  LocalWorkers fakes;
  fakes.startFake(n, port, a.fakeSeconds, store);
  ServiceClient c("127.0.0.1:" + std::to_string(port), wire::ClientSecurity{});
  if (!c.waitForWorkers(n, 120)) throw std::runtime_error("bench service: the fake workers did not connect");
  // backlit's job with its views repeated to one per worker, one shard each, every view every step.
  v1::JobSpec job = zooJob("backlit");
  v1::Scene scene = zooScene("backlit");
  std::vector<v1::Camera> cams(scene.views().begin(), scene.views().end());
  scene.clear_views();
  for (int v = 0; v < n; ++v) *scene.add_views() = cams[size_t(v) % cams.size()];
  *job.mutable_scene() = scene;
  auto* opt = job.mutable_optimization();
  opt->set_shards(n);
  opt->set_views_per_step(n);
  opt->set_steps(a.steps);
  double rssStart = residentMb(), rssAfterFirst = 0, rssEnd = 0, cpu0 = 0;
  std::vector<double> stepSeconds, ownSeconds;
  double prev = -1;
  auto r = c.submit(job, "");
  std::atomic<bool> never{false};
  auto final = c.watch(r.job_id(), 0, [&](const v1::ProgressEvent& e) {
    if (!e.has_step()) return;
    if (prev >= 0) {
      stepSeconds.push_back(e.step().seconds() - prev);
      ownSeconds.push_back(e.step().transport_seconds() + e.step().update_seconds());
    } else {
      rssAfterFirst = residentMb();
      cpu0 = cpuSeconds();
    }
    prev = e.step().seconds();
  }, never);
  const double cpu = cpuSeconds() - cpu0;
  rssEnd = residentMb();
  if (!final || final->state() != v1::SUCCEEDED) throw std::runtime_error("bench service: fake job did not succeed: " + (final ? final->reason() : ""));
  srv->shutdown();  // the fake workers' streams end: they write their byte counts and exit
  uint64_t tasks = 0, taskBytes = 0, resultBytes = 0;
  for (int i = 1; i <= n; ++i) {
    auto f = store / ("fake-" + std::to_string(i) + ".stats");
    for (int k = 0; k < 100 && !std::filesystem::exists(f); ++k) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    uint64_t t = 0, in = 0, out = 0;
    std::ifstream(f) >> t >> in >> out;
    tasks += t, taskBytes += in, resultBytes += out;
  }
  fakes.stop();
  srv.reset();
  std::filesystem::remove_all(store);
  double wall = 0, own = 0;
  for (size_t i = 0; i < stepSeconds.size(); ++i) wall += stepSeconds[i], own += ownSeconds[i];
  std::cerr << "fake workers: " << n << " workers, " << a.steps << " steps of " << a.fakeSeconds << " s simulated compute: server CPU "
            << cpu << " s over " << wall << " s of steps; resident " << rssStart << " -> " << rssAfterFirst << " -> " << rssEnd << " MiB\n";
  BenchReport rep("service_fake_workers");
  rep.number("fake_workers", n);
  rep.number("server_cpu_fraction", cpu / std::max(wall, 1e-9));
  rep.number("service_time_fraction", own / std::max(wall, 1e-9));
  rep.number("seconds_per_step", wall / std::max<double>(1, double(stepSeconds.size())), "s");
  rep.number("server_cpu_ms_per_step", 1e3 * cpu / std::max<double>(1, double(stepSeconds.size())), "ms");
  rep.number("server_rss_mb_after_first_step", rssAfterFirst, "MiB");
  rep.number("server_rss_mb_end", rssEnd, "MiB");
  rep.number("task_bytes_per_step", double(taskBytes) / double(std::max<uint64_t>(1, tasks)) * n, "B");
  rep.number("result_bytes_per_step", double(resultBytes) / double(std::max<uint64_t>(1, tasks)) * n, "B");
  rep.print(a.json);
}

void run(const BenchServiceArgs& a) {
  if (a.fakeWorkers > 0) return runFake(a);
  spdlog::set_level(spdlog::level::err);
  int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  // Overhead: cornell's built-in job, short targets (they are not timed).
  v1::JobSpec one = zooJob("cornell");
  one.mutable_optimization()->set_steps(a.steps);
  one.mutable_optimization()->set_target_spp(16);
  // Interleaved, best of `repeats` each: the machine is shared, and drift between two single
  // runs is larger than the overhead being measured.
  double inproc = 1e30, service = 1e30, accounted = 1e30;
  for (int r = 0; r < a.repeats; ++r) {
    inproc = std::min(inproc, inProcessSecondsPerStep(one, cores));
    service = std::min(service, serviceSecondsPerStep(one, 1, cores));
    accounted = std::min(accounted, gAccountedOverhead);
  }
  double overhead = service / inproc - 1.0;
  std::cerr << "overhead: cornell, " << a.steps << " steps: in process " << inproc * 1e3 << " ms/step, service with 1 worker ("
            << cores << " threads) " << service * 1e3 << " ms/step\n";
  // Scaling: backlit's 16 views in 2 shards, every view every step: compute-bound.
  v1::JobSpec many = zooJob("backlit");
  many.mutable_optimization()->set_steps(std::max(4, a.steps / 2));
  many.mutable_optimization()->set_target_spp(4);
  many.mutable_optimization()->set_views_per_step(16);
  many.mutable_optimization()->set_shards(2);
  double w1 = 1e30, w2 = 1e30;
  for (int r = 0; r < a.repeats; ++r) {
    w1 = std::min(w1, serviceSecondsPerStep(many, 1, 1));
    w2 = std::min(w2, serviceSecondsPerStep(many, 2, 1));
  }
  double speedup = w1 / w2;
  std::cerr << "scaling: backlit, 16 views in 2 shards: 1 worker " << 1.0 / w1 << " steps/s, 2 workers " << 1.0 / w2 << " steps/s\n";
  // Two jobs at once: backlit twice (other seeds), two shards each, on two single-threaded workers.
  std::vector<v1::JobSpec> pair = {many, many};
  pair[1].mutable_optimization()->set_seed(many.optimization().seed() + 1);
  double apart = 1e30, together = 1e30, shareFirst = 0;
  for (int r = 0; r < a.repeats; ++r) {
    std::vector<double> ws;
    apart = std::min(apart, twoJobsSeconds(pair, false, ws));
    double t = twoJobsSeconds(pair, true, ws);
    if (t < together) together = t, shareFirst = ws[0] / std::max(ws[0] + ws[1], 1e-9);
  }
  std::cerr << "two jobs: backlit twice on 2 workers: back to back " << apart << " s, together " << together << " s (first job's share "
            << shareFirst << ")\n";
  BenchReport rep("service");
  rep.number("overhead_one_worker", overhead);
  rep.number("speedup_two_workers", speedup);
  // The service's own share of each step by its clocks: transport (step wall time minus the
  // slowest worker's compute) plus the optimiser update and checkpoint.
  rep.number("service_time_fraction", accounted);
  rep.number("inprocess_seconds_per_step", inproc, "s");
  rep.number("service_seconds_per_step", service, "s");
  rep.number("one_worker_steps_per_second", 1.0 / w1);
  rep.number("two_workers_steps_per_second", 1.0 / w2);
  rep.number("concurrent_throughput_ratio", apart / together);
  rep.number("concurrent_share_first", shareFirst);
  rep.number("back_to_back_seconds", apart, "s");
  rep.number("together_seconds", together, "s");
  rep.print(a.json);
}

}  // namespace

void addBenchServiceCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<BenchServiceArgs>();
  auto* c = bench.add_subcommand("service", "Service overhead with one worker, speed-up with two, two jobs at once (targets: <= 0.05, >= 1.6, >= 0.9 and share 0.5 +- 0.1)");
  c->add_option("--steps", a->steps, "steps per timed job")->capture_default_str()->check(CLI::Range(3, 10000));
  c->add_option("--repeats", a->repeats, "interleaved repetitions (best of)")->capture_default_str()->check(CLI::Range(1, 100));
  c->add_flag("--json", a->json, "print the figures as JSON");
  c->add_option("--fake-workers", a->fakeWorkers,
                "instead: the server alone with N workers that render nothing (canned answers of the job's size after "
                "--fake-seconds): its CPU time per step (target <= 0.05 of the step), memory and message sizes")
      ->check(CLI::Range(1, 256));
  c->add_option("--fake-seconds", a->fakeSeconds, "simulated compute per task of a fake worker")->capture_default_str()->check(invr::wire::kPositive);
  c->callback([a, &exitCode] {
    run(*a);
    exitCode = 0;
  });
}

}  // namespace invr::cli
