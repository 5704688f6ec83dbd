// Integration tests: real invr-server and invr-worker processes on loopback, ephemeral ports.
#include "tests/service/cluster.h"

#include <grpcpp/generic/generic_stub.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include "reflection_probe.grpc.pb.h"

namespace invr {
namespace {

using namespace invr::test;
namespace v1 = invr::v1;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

TEST(Service, SubmitCompleteFetchMatchesInProcessBitForBit) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  v1::JobSpec job = smallJob("cornell", 4);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_FALSE(evs.empty());
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_EQ(stepsOf(evs), (std::vector<uint64_t>{1, 2, 3, 4}));
  for (size_t i = 1; i < evs.size(); ++i) EXPECT_EQ(evs[i].sequence(), evs[i - 1].sequence() + 1);

  // Same job, same arithmetic in this process: identical bits.
  EXPECT_EQ(c.checkpointTheta(id), inProcess(job));

  // Every listed result can be fetched, in chunks.
  v1::JobStatus st = c.get(id);
  EXPECT_GE(st.results_size(), 5);
  for (const auto& name : st.results()) {
    grpc::ClientContext ctx;
    v1::FetchResultRequest req;
    req.set_job_id(id);
    req.set_name(name);
    auto r = c.stub().FetchResult(&ctx, req);
    v1::AssetChunk ch;
    size_t bytes = 0;
    while (r->Read(&ch)) bytes += ch.data().size();
    EXPECT_TRUE(r->Finish().ok()) << name;
    EXPECT_GT(bytes, 0u) << name;
  }

  // Watching again from a sequence number resumes there.
  uint64_t from = evs[evs.size() / 2].sequence();
  auto again = c.watch(id, from);
  ASSERT_FALSE(again.empty());
  EXPECT_EQ(again.front().sequence(), from);
  EXPECT_EQ(again.size(), evs.size() - evs.size() / 2);
  EXPECT_TRUE(again.back().has_final());
}

// Runs `job` to its end on a fresh server with `workers` one-thread workers: its events, final
// parameters and status.
struct ClusterRun {
  std::vector<v1::ProgressEvent> events;
  std::vector<float> theta;
  v1::JobStatus status;
};
ClusterRun runOnWorkers(const v1::JobSpec& job, int workers) {
  TempDir tmp;
  Cluster c(tmp.path);
  // startWorker() waits until each worker is connected: no grace period to wait for more.
  c.startServer(0, {"--assign-grace", "0"});
  for (int w = 0; w < workers; ++w) c.startWorker(1);
  std::string id;
  ClusterRun run;
  EXPECT_TRUE(c.submit(job, &id).ok());
  run.events = c.watch(id);
  if (run.events.empty()) {
    ADD_FAILURE() << "the job sent no events";
    return run;
  }
  EXPECT_EQ(run.events.back().final().state(), v1::SUCCEEDED) << run.events.back().final().reason();
  run.theta = c.checkpointTheta(id);
  run.status = c.get(id);
  return run;
}

TEST(Service, TwoWorkersGiveTheSameParametersAsOne) {
  // Two shards, mini-batches of 4 of the 16 views: each shard sees a different subset per step.
  v1::JobSpec job = smallJob("backlit", 3);
  job.mutable_optimization()->set_shards(2);
  job.mutable_optimization()->set_target_spp(2);
  std::vector<float> theta[2];
  for (int workers = 1; workers <= 2; ++workers) theta[workers - 1] = runOnWorkers(job, workers).theta;
  EXPECT_EQ(theta[0], theta[1]);
  EXPECT_EQ(theta[0], inProcess(job));
}

TEST(Service, TwoJobsAtOnceShareTheWorkersAndGiveTheirAloneNumbers) {
  // Two jobs of two shards each, submitted together to two workers: both run at once (each
  // worker holds sessions of both), and each job's parameters are those of it alone in process.
  v1::JobSpec a = smallJob("backlit", 3);
  a.mutable_optimization()->set_shards(2);
  a.mutable_optimization()->set_target_spp(2);
  v1::JobSpec b = a;  // another job: other random streams
  b.mutable_optimization()->set_seed(a.optimization().seed() + 1);
  b.mutable_scheduling()->set_priority(3);
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(1);
  c.startWorker(1);
  std::string ida, idb;
  ASSERT_TRUE(c.submit(a, &ida).ok());
  grpc::Status sb0 = c.submit(b, &idb);
  ASSERT_TRUE(sb0.ok()) << sb0.error_message();
  // They run at the same time: both RUNNING at once (targets take seconds to render, so a
  // 20 ms poll sees it).
  bool together = false;
  for (int i = 0; i < 1500 && !together; ++i) {
    together = c.get(ida).state() == v1::RUNNING && c.get(idb).state() == v1::RUNNING;
    if (!together) std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(together) << "the two jobs never ran at the same time";
  auto ea = c.watch(ida);
  auto eb = c.watch(idb);
  ASSERT_FALSE(ea.empty());
  ASSERT_FALSE(eb.empty());
  ASSERT_EQ(ea.back().final().state(), v1::SUCCEEDED) << ea.back().final().reason();
  ASSERT_EQ(eb.back().final().state(), v1::SUCCEEDED) << eb.back().final().reason();
  EXPECT_EQ(c.checkpointTheta(ida), inProcess(a));
  EXPECT_EQ(c.checkpointTheta(idb), inProcess(b));
  v1::JobStatus sa = c.get(ida), sb = c.get(idb);
  EXPECT_EQ(sa.priority(), 1u);
  EXPECT_EQ(sb.priority(), 3u);
  EXPECT_GT(sa.worker_seconds(), 0.0);
  EXPECT_GT(sb.worker_seconds(), 0.0);
}

TEST(Service, SchedulingFieldsOutOfRangeAreRejectedNamingTheField) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  v1::JobSpec job = smallJob("cornell", 1);
  job.mutable_scheduling()->set_priority(101);
  std::string id;
  grpc::Status st = c.submit(job, &id);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("scheduling.priority"), std::string::npos) << st.error_message();
  job.mutable_scheduling()->set_priority(1);
  job.mutable_scheduling()->set_max_workers(5000);
  st = c.submit(job, &id);
  EXPECT_NE(st.error_message().find("scheduling.max_workers"), std::string::npos) << st.error_message();
}

TEST(Service, VarianceJobsMatchInProcessWithAnyWorkerCount) {
  // A variance-aware job (Yan et al. 2024) over two shards: the variance pass, its loss terms
  // and the render cost travel through the service and sum as in process.
  v1::JobSpec job = smallJob("backlit", 3);
  auto* o = job.mutable_optimization();
  o->set_method(v1::METHOD_PT);
  o->set_shards(2);
  o->set_target_spp(2);
  o->mutable_variance()->set_samples(4);
  std::vector<float> theta[2];
  for (int workers = 1; workers <= 2; ++workers) {
    ClusterRun run = runOnWorkers(job, workers);
    theta[workers - 1] = run.theta;
    const auto& evs = run.events;
    int steps = 0;
    for (const auto& e : evs) {
      if (!e.has_step()) continue;
      ++steps;
      const auto& sp = e.step().stats();
      EXPECT_EQ(e.step().loss(), sp.loss());
      EXPECT_GT(sp.variance_term(), 0.0);
      EXPECT_GT(sp.cost(), 1.0) << "a camera ray and a shadow ray at least";
      EXPECT_NEAR(sp.loss(), sp.bias_term() + sp.variance_term(), 1e-9 * (1 + std::abs(sp.loss())));
      EXPECT_GT(sp.seconds_variance(), 0.0);
    }
    EXPECT_EQ(steps, 3);
    const auto& results = run.status.results();
    EXPECT_NE(std::find(results.begin(), results.end(), "variance_view0.exr"), results.end());
  }
  EXPECT_EQ(theta[0], theta[1]);
  EXPECT_EQ(theta[0], inProcess(job));
}

TEST(Service, SamplingParameterJobsWriteTheirSelectionMaps) {
  v1::JobSpec job = zooJob("spot");
  job.mutable_optimization()->set_steps(2);
  job.mutable_optimization()->set_target_spp(4);
  ClusterRun run = runOnWorkers(job, 1);
  EXPECT_EQ(run.theta, inProcess(job));
  const auto& results = run.status.results();
  for (const char* f : {"light_selection.csv", "selection_view0.exr", "variance_view0.exr", "parameters.json"})
    EXPECT_NE(std::find(results.begin(), results.end(), f), results.end()) << f;
}

// Runs backlit (two shards) on two workers, disturbs one after step `after`, and returns every
// event of the job once it has ended.
std::vector<v1::ProgressEvent> runAndDisturb(Cluster& c, int steps, uint64_t after, const std::function<void()>& disturb) {
  c.startServer();
  c.startWorker(1);
  c.startWorker(1);
  v1::JobSpec job = smallJob("backlit", steps);
  job.mutable_optimization()->set_shards(2);
  std::string id;
  EXPECT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id, 0, [&](const v1::ProgressEvent& e) { return e.has_step() && e.step().step() >= after; });
  disturb();
  auto rest = c.watch(id, evs.back().sequence() + 1);
  evs.insert(evs.end(), rest.begin(), rest.end());
  return evs;
}

std::vector<uint64_t> oneTo(uint64_t n) {
  std::vector<uint64_t> v(n);
  std::iota(v.begin(), v.end(), 1);
  return v;
}

TEST(Service, WorkerKilledMidJobTheJobCompletesAndNoStepRepeats) {
  TempDir tmp;
  Cluster c(tmp.path);
  auto evs = runAndDisturb(c, 12, 3, [&] { c.killWorker(0); });
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_EQ(stepsOf(evs), oneTo(12));  // every step once, in order
  std::string log;
  for (const auto& e : evs)
    if (e.has_message()) log += e.message() + "\n";
  EXPECT_TRUE(anyMessage(evs, "lost")) << "progress should say a worker was lost:\n" << log;
}

TEST(Service, ServerKilledMidJobResumesFromItsCheckpoint) {
  TempDir tmp;
  Cluster c(tmp.path);
  int port = c.startServer();
  c.startWorker(2);
  v1::JobSpec job = smallJob("cornell", 10);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  c.watch(id, 0, [](const v1::ProgressEvent& e) { return e.has_step() && e.step().step() >= 3; });
  c.killServer();
  c.startServer(port);  // same store, same address: the worker reconnects
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_EQ(evs.back().final().step(), 10u);
  EXPECT_TRUE(anyMessage(evs, "resumed from checkpoint at step"));
  // Step numbers after the resume continue from the checkpoint, each once.
  std::vector<uint64_t> steps = stepsOf(evs);
  ASSERT_FALSE(steps.empty());
  EXPECT_EQ(steps.back(), 10u);
}

TEST(Service, CancelWhileRunningIsIdempotent) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  std::string id;
  ASSERT_TRUE(c.submit(smallJob("cornell", 100000), &id).ok());
  c.watch(id, 0, [](const v1::ProgressEvent& e) { return e.has_step() && e.step().step() >= 2; });
  for (int i = 0; i < 2; ++i) {
    grpc::ClientContext ctx;
    v1::CancelJobRequest req;
    req.set_job_id(id);
    v1::JobStatus s;
    ASSERT_TRUE(c.stub().CancelJob(&ctx, req, &s).ok());
  }
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::CANCELLED);
  EXPECT_LT(evs.back().final().step(), 100000u);
  EXPECT_EQ(c.get(id).state(), v1::CANCELLED);
}

TEST(Service, FullQueueIsResourceExhausted) {
  TempDir tmp;
  Cluster c(tmp.path);
  // No workers, one job at a time: the first job runs (waiting), the next queues.
  c.startServer(0, {"--max-queued", "1", "--max-running-jobs", "1"});
  std::string a, b;
  ASSERT_TRUE(c.submit(smallJob("cornell", 5), &a).ok());
  for (int i = 0; i < 100 && c.get(a).state() != v1::RUNNING; ++i) std::this_thread::sleep_for(50ms);
  ASSERT_TRUE(c.submit(smallJob("cornell", 5), &b).ok());
  EXPECT_EQ(c.get(b).state(), v1::QUEUED);
  grpc::Status st = c.submit(smallJob("cornell", 5), nullptr);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(st.error_message().find("queue full"), std::string::npos) << st.error_message();
}

TEST(Service, BadInputIsRejectedWithTheFieldAndTheServerKeepsServing) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer(0, {"--max-asset-mb", "0.001"});
  auto expectError = [&](v1::JobSpec job, grpc::StatusCode code, const std::string& needle) {
    grpc::Status st = c.submit(job, nullptr);
    EXPECT_EQ(st.error_code(), code) << needle << ": " << st.error_message();
    EXPECT_NE(st.error_message().find(needle), std::string::npos) << st.error_message();
  };
  v1::JobSpec j = smallJob("cornell", 3);
  j.mutable_optimization()->mutable_parameters(0)->set_name("materials/rouge/albedo");
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "optimization.parameters[0].name");
  j = smallJob("cornell", 3);
  j.mutable_optimization()->mutable_parameters(0)->set_initial(std::nan(""));
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "optimization.parameters[0].initial");
  j = smallJob("cornell", 3);
  j.mutable_optimization()->mutable_parameters(0)->set_lower(0.8);
  j.mutable_optimization()->mutable_parameters(0)->set_upper(0.2);
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "bounds are inverted");
  j = smallJob("cornell", 3);
  j.mutable_optimization()->set_steps(0);
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "optimization.steps");
  j = smallJob("cornell", 3);
  j.mutable_optimization()->add_targets()->set_sha256(std::string(64, 'a'));
  expectError(j, grpc::StatusCode::NOT_FOUND, "optimization.targets[0].sha256");
  j = smallJob("cornell", 3);
  j.mutable_optimization()->add_targets()->set_path("/home/me/target.exr");
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "optimization.targets[0].path");
  j = smallJob("cornell", 3);
  j.clear_optimization();
  expectError(j, grpc::StatusCode::INVALID_ARGUMENT, "optimization.parameters");

  // An upload over the server's limit (1 KiB here).
  {
    grpc::ClientContext ctx;
    v1::AssetInfo info;
    auto w = c.stub().UploadAsset(&ctx, &info);
    v1::AssetChunk ch;
    ch.set_data(std::string(4096, 'x'));
    w->Write(ch);
    w->WritesDone();
    grpc::Status st = w->Finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  }
  // A small upload is stored under its SHA-256.
  {
    grpc::ClientContext ctx;
    v1::AssetInfo info;
    auto w = c.stub().UploadAsset(&ctx, &info);
    v1::AssetChunk ch;
    ch.set_data("abc");
    w->Write(ch);
    w->WritesDone();
    ASSERT_TRUE(w->Finish().ok());
    EXPECT_EQ(info.sha256(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  }
  // Unknown job ids.
  {
    grpc::ClientContext ctx;
    v1::GetJobRequest req;
    req.set_job_id("job-999999");
    v1::JobStatus s;
    EXPECT_EQ(c.stub().GetJob(&ctx, req, &s).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  // Still serving; a retried submission with the same request id is the same job.
  std::string a, b;
  ASSERT_TRUE(c.submit(smallJob("cornell", 3), &a, "req-1").ok());
  ASSERT_TRUE(c.submit(smallJob("cornell", 3), &b, "req-1").ok());
  EXPECT_EQ(a, b);
  grpc::ClientContext ctx;
  v1::ListJobsResponse all;
  ASSERT_TRUE(c.stub().ListJobs(&ctx, v1::ListJobsRequest(), &all).ok());
  EXPECT_EQ(all.jobs_size(), 1);
}

TEST(Service, WorkerSigtermFinishesItsTaskAndLeaves) {
  TempDir tmp;
  Cluster c(tmp.path);
  int status = -1;
  auto evs = runAndDisturb(c, 8, 2, [&] { status = c.terminateWorker(0); });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_EQ(stepsOf(evs), oneTo(8));
}

TEST(Service, AWorkerStoppedMidTaskHandsItBackWithoutCostingAnAttempt) {
  // One attempt per shard: a counted failure would fail the job. The first worker is stopped
  // while it renders its shard's targets (seconds at 128 spp) with no drain time: it tells the
  // server it is leaving, abandons the task, and the shard moves to the other worker.
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer(0, {"--max-attempts", "1", "--assign-grace", "0"});
  c.startWorker(1, {"--drain-seconds", "0"});
  v1::JobSpec job = smallJob("cornell", 2);
  job.mutable_optimization()->set_target_spp(128);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  c.watch(id, 0, [](const v1::ProgressEvent& e) { return e.has_message() && e.message().rfind("started", 0) == 0; });
  std::this_thread::sleep_for(500ms);  // the first task is out, rendering targets
  c.startWorker(1);
  auto t0 = std::chrono::steady_clock::now();
  int status = c.terminateWorker(0);
  double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
  EXPECT_LT(took, 5.0) << "the worker kept rendering instead of handing the task back";
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_TRUE(anyMessage(evs, "left and handed its task back"));
}

TEST(Service, ExpiredLeasesFailTheJobAfterBoundedAttempts) {
  TempDir tmp;
  Cluster c(tmp.path);
  // Leases of 50 ms cannot cover building a session (rendering targets at 16 spp, seconds on one
  // thread; the lease is checked every 100 ms).
  // A worker whose lease expired gets the next lease once it proves alive, so every lease must be
  // too short: 50 ms is less than one gradient step.
  c.startServer(0, {"--lease-seconds", "0.05", "--max-attempts", "2"});
  c.startWorker(1);
  v1::JobSpec job = smallJob("cornell", 3);
  job.mutable_optimization()->set_target_spp(16);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::FAILED);
  EXPECT_NE(evs.back().final().reason().find("failed 2 times"), std::string::npos) << evs.back().final().reason();
  EXPECT_NE(evs.back().final().reason().find("expired"), std::string::npos) << evs.back().final().reason();
  // The server still serves.
  EXPECT_EQ(c.get(id).state(), v1::FAILED);
}

TEST(Service, UploadedTargetImagesAreUsedAndNoParameterErrorIsClaimed) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  // The target: cornell rendered with its true albedos, written as EXR and uploaded.
  v1::JobSpec job = smallJob("cornell", 3);
  {
    Problem p = buildProblem(job);
    writeImage(tmp.path / "target.exr", renderTarget(p, 0));
  }
  std::ifstream in(tmp.path / "target.exr", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  job.mutable_optimization()->add_targets()->set_sha256(c.upload(bytes));
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_LT(evs.back().final().param_error(), 0.0);  // no ground truth: not reported
  // Same images as the synthetic job's, so the same parameters.
  v1::JobSpec synthetic = smallJob("cornell", 3);
  EXPECT_EQ(c.checkpointTheta(id), inProcess(synthetic));
}

TEST(Service, ParameterVectorsBeyondFourMebibytesTravel) {
  // A 1024x1024 albedo texture: 3.1M parameters, 12 MiB of theta per task and 24 MiB of gradient
  // per result, against gRPC's 4 MiB default.
  const char* json = R"({
  "name": "big-texture",
  "scene": {
    "materials": [
      {"name": "canvas", "diffuse": {"albedo": {"procedural": {"pattern": "checker", "width": 1024,
        "color_a": {"r": 0.7, "g": 0.6, "b": 0.5}, "color_b": {"r": 0.2, "g": 0.3, "b": 0.4}}}}},
      {"name": "lamp", "diffuse": {"albedo": {"value": 0.5}}}
    ],
    "shapes": [
      {"name": "canvas", "material": "canvas", "quad": {}},
      {"name": "lamp", "material": "lamp", "quad": {},
       "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"x": 180}, "translate": {"z": 2}}}
    ],
    "lights": [{"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 10, "g": 10, "b": 10}}}],
    "views": [{"name": "front", "eye": {"z": 3}, "target": {}, "fov_y_degrees": 40}],
    "film": {"width": 32, "height": 32}
  },
  "optimization": {
    "parameters": [{"name": "materials/canvas/albedo", "initial": 0.5, "learning_rate": 0.01}],
    "steps": 2, "target_spp": 2, "seed": "3"
  }
}
)";
  v1::JobSpec job = parseJobJson(json, "big.json");
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  std::vector<float> theta = c.checkpointTheta(id);
  EXPECT_EQ(theta.size(), 3u * 1024 * 1024);
  EXPECT_EQ(theta, inProcess(job));
}

TEST(Service, EvictedSessionsAreRebuiltAndTheJobCompletes) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer(0, {"--assign-grace", "0"});
  c.startWorker(2, {"--max-sessions", "1"});  // two shards, room for one session
  v1::JobSpec job = smallJob("backlit", 3);
  job.mutable_optimization()->set_shards(2);
  job.mutable_optimization()->set_target_spp(2);  // every eviction renders the shard's targets again
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  std::ifstream log(c.workerLog(0));
  std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("evicting session"), std::string::npos);
}

// grpc.health.v1.Health/Check with an empty request on `address`; the response bytes (SERVING
// is field 1 = 1: "\x08\x01").
std::pair<grpc::Status, std::string> healthCheck(const std::string& address) {
  auto ch = wire::channel(address);
  grpc::GenericStub generic(ch);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + 10s);
  grpc::ByteBuffer resp;
  grpc::Slice empty("", 0);
  grpc::ByteBuffer req(&empty, 1);
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  grpc::Status st;
  generic.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &req, &resp, [&](grpc::Status s) {
    std::lock_guard<std::mutex> lk(m);
    st = s;
    done = true;
    cv.notify_all();
  });
  std::unique_lock<std::mutex> lk(m);
  cv.wait_for(lk, 15s, [&] { return done; });
  std::string bytes;
  std::vector<grpc::Slice> slices;
  if (done && st.ok() && resp.Dump(&slices).ok())
    for (auto& sl : slices) bytes.append(reinterpret_cast<const char*>(sl.begin()), sl.size());
  return {done ? st : grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "no answer"), bytes};
}

int freePort() {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

TEST(Service, MetricsAndThePlaintextHealthListenerAreServedWithoutTokens) {
  TempDir tmp;
  Cluster c(tmp.path);
  { std::ofstream(tmp.path / "client.tok") << "client-secret\n"; }
  const int metrics = freePort(), health = freePort();
  // The worker API is open here (Cluster's workers carry no token); the client API is not.
  c.startServer(0, {"--metrics-address", "127.0.0.1:" + std::to_string(metrics), "--health-address", "127.0.0.1:" + std::to_string(health),
                    "--client-token-file", (tmp.path / "client.tok").string()});
  // The health service needs no token, on either port.
  for (const std::string& a : {"127.0.0.1:" + std::to_string(health), c.address()}) {
    auto [st, bytes] = healthCheck(a);
    EXPECT_TRUE(st.ok()) << a << ": " << st.error_message();
    EXPECT_EQ(bytes, std::string("\x08\x01", 2)) << a;
  }
  // The client API does.
  std::string id;
  EXPECT_EQ(c.submit(smallJob("cornell", 1), &id).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  httplib::Client http("127.0.0.1", metrics);
  auto scrape = [&] {
    auto r = http.Get("/metrics");
    EXPECT_TRUE(r && r->status == 200);
    return r ? r->body : std::string();
  };
  std::string body = scrape();
  for (const char* line : {"invr_queue_depth 0", "invr_running_jobs 0", "invr_connected_workers 0", "invr_steps_total 0",
                           "invr_step_seconds_count 0", "# TYPE invr_step_seconds histogram", "invr_jobs{state=\"succeeded\"} 0"})
    EXPECT_NE(body.find(line), std::string::npos) << line << "\n" << body;
  // A job of 2 steps, submitted with the token: the counters follow.
  c.startWorker(1);
  {
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer client-secret");
    v1::SubmitJobRequest req;
    *req.mutable_spec() = smallJob("cornell", 2);
    v1::SubmitJobResponse resp;
    ASSERT_TRUE(c.stub().SubmitJob(&ctx, req, &resp).ok());
    id = resp.job_id();
  }
  for (int i = 0; i < 600 && scrape().find("invr_jobs{state=\"succeeded\"} 1") == std::string::npos; ++i) std::this_thread::sleep_for(100ms);
  body = scrape();
  for (const char* line : {"invr_steps_total 2", "invr_step_seconds_count 2", "invr_connected_workers 1", "invr_jobs{state=\"succeeded\"} 1",
                           "invr_running_jobs 0", "invr_step_seconds_bucket{le=\"+Inf\"} 2"})
    EXPECT_NE(body.find(line), std::string::npos) << line << "\n" << body;
}

TEST(Service, HealthAndReflectionAreServed) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  auto [st, bytes] = healthCheck(c.address());
  EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(bytes, std::string("\x08\x01", 2));
  auto ch = wire::channel(c.address());

  // Server reflection lists both services.
  auto refl = grpc::reflection::v1alpha::ServerReflection::NewStub(ch);
  grpc::ClientContext rctx;
  auto stream = refl->ServerReflectionInfo(&rctx);
  grpc::reflection::v1alpha::ServerReflectionRequest rq;
  rq.set_list_services("");
  ASSERT_TRUE(stream->Write(rq));
  stream->WritesDone();
  grpc::reflection::v1alpha::ServerReflectionResponse rr;
  ASSERT_TRUE(stream->Read(&rr));
  std::set<std::string> names;
  for (const auto& sv : rr.list_services_response().service()) names.insert(sv.name());
  EXPECT_TRUE(stream->Finish().ok());
  EXPECT_TRUE(names.count("invr.v1.InvrService"));
  EXPECT_TRUE(names.count("invr.v1.WorkerService"));
}

}  // namespace
}  // namespace invr
