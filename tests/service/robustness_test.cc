// Integration tests for what a hostile or faulty user, client or worker can send: malformed files,
// oversized headers, unknown enums, a worker answering with the wrong shapes, a worker that
// stalls, a cancel during a long render, a server restart under `invr watch`, a second server.
// Each asserts the job's outcome and that the server keeps serving.
#include <netinet/in.h>
#include <sys/socket.h>

#include <atomic>
#include <cstdio>
#include <ctime>
#include <cstdint>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>

#include <grpcpp/generic/generic_stub.h>

#include "core/job/problem.h"
#include "core/scene/zoo.h"
#include "tests/service/cluster.h"
#include "tests/test_util.h"

namespace invr {
namespace {

using namespace invr::test;
namespace v1 = invr::v1;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A valid small job still runs to the end: the server is healthy.
void expectHealthy(Cluster& c) {
  std::string id;
  ASSERT_TRUE(c.submit(smallJob("cornell", 2), &id).ok());
  auto evs = c.watch(id);
  ASSERT_FALSE(evs.empty());
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
}

// Cornell as an inline scene, so tests can put uploaded assets into it.
v1::JobSpec inlineCornell() {
  v1::JobSpec job = smallJob("cornell", 2);
  *job.mutable_scene() = zooScene("cornell");
  return job;
}

grpc::Status submitWith(Cluster& c, const v1::JobSpec& job) { return c.submit(job, nullptr); }

// Until the server counts n connected workers (the Cluster's own and the test's scripted ones).
void waitForWorkers(Cluster& c, int n) {
  for (int i = 0; i < 400; ++i) {
    grpc::ClientContext ctx;
    v1::ListWorkersResponse r;
    if (c.stub().ListWorkers(&ctx, v1::ListWorkersRequest(), &r).ok() && r.workers_size() >= n) return;
    std::this_thread::sleep_for(25ms);
  }
  FAIL() << "fewer than " << n << " workers connected";
}

TEST(Robustness, MalformedFilesOversizedHeadersAndBadEnumsAreRefusedAndTheServerKeepsServing) {
  TempDir tmp;
  Cluster c(tmp.path);
  // A small job budget keeps the procedural-texture case cheap: 4096^2 RGB floats are 192 MiB.
  c.startServer(0, {"--max-job-memory-mb", "300"});
  c.startWorker(2);

  auto withMesh = [&](const std::string& bytes) {
    v1::JobSpec job = inlineCornell();
    auto* shape = job.mutable_scene()->add_shapes();
    shape->set_name("user_mesh");
    shape->set_material("white");
    shape->mutable_mesh()->set_sha256(c.upload(bytes));
    return job;
  };
  // An OBJ whose faces name normal 5 of 1 (once read past the array and crashed the server).
  grpc::Status st = submitWith(c, withMesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//5 2//5 3//5\n"));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_NE(st.error_message().find("references normal 5 of 1"), std::string::npos) << st.error_message();
  EXPECT_NE(st.error_message().find("scene.shapes[8] (user_mesh)"), std::string::npos) << st.error_message();
  // Texture coordinates likewise.
  st = submitWith(c, withMesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/9 3/1\n"));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_NE(st.error_message().find("texture coordinate 9 of 1"), std::string::npos) << st.error_message();
  // PLY face counts beyond the limit or negative.
  const std::string plyHead = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  st = submitWith(c, withMesh(plyHead + "element face 4000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  EXPECT_NE(st.error_message().find("declares 4000000000"), std::string::npos) << st.error_message();
  st = submitWith(c, withMesh(plyHead + "element face -1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_NE(st.error_message().find("count '-1'"), std::string::npos) << st.error_message();

  // A Mitsuba scene reference: the client imports it; the server refuses to read a client's XML.
  {
    v1::JobSpec job = inlineCornell();
    job.mutable_mitsuba()->set_path("scene.xml");
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_NE(st.error_message().find("imported into 'scene' by the client"), std::string::npos) << st.error_message();
  }
  // A mask entry left empty is fine; a mask naming an asset never uploaded is not found.
  {
    v1::JobSpec job = inlineCornell();
    job.mutable_optimization()->add_target_masks()->set_sha256(std::string(64, 'a'));
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << st.error_message();
    EXPECT_NE(st.error_message().find("optimization.target_masks[0].sha256"), std::string::npos) << st.error_message();
  }

  // A PNG texture declaring 30000x30000 pixels: refused from its header, nothing allocated.
  {
    v1::JobSpec job = inlineCornell();
    job.mutable_scene()->mutable_materials(0)->mutable_diffuse()->mutable_albedo()->mutable_image()->set_sha256(
        c.upload(pngDeclaringSize(30000, 30000)));
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
    EXPECT_NE(st.error_message().find("30000x30000 pixels (limit 16384 per side)"), std::string::npos) << st.error_message();
    EXPECT_NE(st.error_message().find("scene.materials[0] (white).diffuse.albedo.image"), std::string::npos) << st.error_message();
  }
  // The same as a target image.
  {
    v1::JobSpec job = smallJob("cornell", 2);
    job.mutable_optimization()->add_targets()->set_sha256(c.upload(pngDeclaringSize(30000, 30000)));
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
    EXPECT_NE(st.error_message().find("optimization.targets[0]"), std::string::npos) << st.error_message();
  }
  // In-bounds procedural textures that together exceed the job's memory budget.
  {
    v1::JobSpec job = inlineCornell();
    for (int m = 0; m < 3; ++m) {
      auto* p = job.mutable_scene()->mutable_materials(m)->mutable_diffuse()->mutable_albedo()->mutable_procedural();
      p->set_pattern("checker");
      p->set_width(4096);
    }
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
    EXPECT_NE(st.error_message().find("memory budget of 300 MiB"), std::string::npos) << st.error_message();
  }
  // Unknown enum numbers are not run as something else.
  {
    v1::JobSpec job = smallJob("cornell", 2);
    job.mutable_optimization()->set_method(static_cast<v1::GradientMethod>(99));
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_NE(st.error_message().find("optimization.method: unknown value 99"), std::string::npos) << st.error_message();
    job = smallJob("cornell", 2);
    job.mutable_render()->set_estimator(static_cast<v1::Estimator>(42));
    st = submitWith(c, job);
    EXPECT_NE(st.error_message().find("render.estimator: unknown value 42"), std::string::npos) << st.error_message();
  }
  // A 4 MiB job name is refused, not logged.
  {
    v1::JobSpec job = smallJob("cornell", 2);
    job.set_name(std::string(size_t(4) << 20, 'x'));
    st = submitWith(c, job);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_NE(st.error_message().find("name: 4194304 bytes long (limit 256)"), std::string::npos) << st.error_message();
    std::ifstream log(tmp.path / "server.log");
    std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
    EXPECT_LT(text.size(), size_t(1) << 20);
  }
  expectHealthy(c);
}

// A worker of the test's own: it dials in and answers every task with what `answer` writes into
// the result (identity fields already set). When `answer` returns false the worker sends nothing
// and stays busy with that task; with `heartbeats` it says so every 200 ms, as a real worker's
// heartbeat thread does while its computation hangs.
class ScriptedWorker {
 public:
  using Answer = std::function<bool(const v1::Task&, v1::TaskResult&)>;
  ScriptedWorker(const std::string& address, std::string name, Answer answer, bool heartbeats = false)
      : name_(std::move(name)), answer_(std::move(answer)), heartbeats_(heartbeats) {
    stub_ = v1::WorkerService::NewStub(wire::channel(address));
    thread_ = std::thread([this] { run(); });
  }
  ~ScriptedWorker() {
    stop_ = true;
    ctx_.TryCancel();
    thread_.join();
  }

 private:
  void run() {
    auto stream = stub_->Connect(&ctx_);
    auto write = [&](const v1::WorkerMessage& m) {
      std::lock_guard<std::mutex> lk(writeMu_);
      return stream->Write(m);
    };
    v1::WorkerMessage hello;
    hello.mutable_hello()->set_name(name_);
    hello.mutable_hello()->set_capacity(1);
    write(hello);
    std::thread heart;
    if (heartbeats_)
      heart = std::thread([&] {
        while (!stop_) {
          v1::WorkerMessage hb;
          hb.mutable_heartbeat()->set_busy_task(busy_.load());
          if (!write(hb)) break;
          std::this_thread::sleep_for(200ms);
        }
      });
    v1::ServerMessage m;
    while (stream->Read(&m)) {
      if (!m.has_task()) continue;
      v1::WorkerMessage out;
      v1::TaskResult& r = *out.mutable_result();
      r.set_task_id(m.task().task_id());
      r.set_job_id(m.task().job_id());
      r.set_shard(m.task().shard());
      const bool reply = answer_(m.task(), r);  // called for every task, so tests can count them
      if (busy_) continue;                       // hung: it never answers again
      if (reply)
        write(out);
      else
        busy_ = m.task().task_id();
    }
    stop_ = true;
    if (heart.joinable()) heart.join();
    stream->Finish();
  }
  std::string name_;
  Answer answer_;
  bool heartbeats_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> busy_{0};
  std::mutex writeMu_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  grpc::ClientContext ctx_;
  std::thread thread_;
};

// A raw unary call: `bytes` sent as the request of `method`, the status that answers it.
grpc::Status rawCall(const std::string& address, const std::string& method, const std::string& bytes) {
  grpc::GenericStub generic(wire::channel(address));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + 20s);
  grpc::Slice slice(bytes.data(), bytes.size());
  grpc::ByteBuffer req(&slice, 1), resp;
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  grpc::Status st;
  generic.UnaryCall(&ctx, method, grpc::StubOptions(), &req, &resp, [&](grpc::Status s) {
    std::lock_guard<std::mutex> lk(m);
    st = s;
    done = true;
    cv.notify_all();
  });
  std::unique_lock<std::mutex> lk(m);
  cv.wait_for(lk, 25s, [&] { return done; });
  return done ? st : grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "no answer");
}

// Bytes that are not the method's request message answer INVALID_ARGUMENT naming the message (gRPC's
// callback API would say UNIMPLEMENTED, as if the method did not exist), and the server goes on.
TEST(Robustness, MalformedRequestBytesAreInvalidArgumentNotUnimplemented) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  // Field 2 (spec) declared 200 bytes long, 3 present; a wire type that does not exist.
  const std::string truncatedSubmit = std::string("\x12\xc8\x01\x0a\x01x", 6);
  const std::string badWireType = std::string("\x0f\x01", 2);
  // Field 1 (job_id) declared 5 bytes long, 1 present.
  const std::string truncatedGet = std::string("\x0a\x05j", 3);
  const std::pair<const char*, std::string> calls[] = {
      {"/invr.v1.InvrService/SubmitJob", truncatedSubmit}, {"/invr.v1.InvrService/SubmitJob", badWireType},
      {"/invr.v1.InvrService/GetJob", truncatedGet},       {"/invr.v1.InvrService/CancelJob", truncatedGet},
      {"/invr.v1.InvrService/PlanJob", truncatedSubmit},   {"/invr.v1.InvrService/ListJobs", badWireType},
      {"/invr.v1.InvrService/ListWorkers", badWireType},   {"/invr.v1.InvrService/ResolveJob", badWireType}};
  for (const auto& [method, bytes] : calls) {
    grpc::Status st = rawCall(c.address(), method, bytes);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << method << ": " << st.error_message();
    EXPECT_NE(st.error_message().find("is not a valid invr.v1."), std::string::npos) << method << ": " << st.error_message();
  }
  // A well-formed raw request still works (an unknown job is NOT_FOUND, not a parse error).
  v1::GetJobRequest get;
  get.set_job_id("job-999999");
  EXPECT_EQ(rawCall(c.address(), "/invr.v1.InvrService/GetJob", get.SerializeAsString()).error_code(), grpc::StatusCode::NOT_FOUND);
  // Streams: a malformed WatchJob or FetchResult request ends its stream with INVALID_ARGUMENT.
  for (const char* method : {"/invr.v1.InvrService/WatchJob", "/invr.v1.InvrService/FetchResult"}) {
    grpc::GenericStub generic(wire::channel(c.address()));
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 20s);
    grpc::CompletionQueue cq;
    grpc::Slice slice(truncatedGet.data(), truncatedGet.size());
    grpc::ByteBuffer req(&slice, 1);
    auto call = generic.PrepareCall(&ctx, method, &cq);
    void* tag = nullptr;
    bool ok = false;
    call->StartCall(reinterpret_cast<void*>(1));
    cq.Next(&tag, &ok);
    call->Write(req, reinterpret_cast<void*>(2));
    cq.Next(&tag, &ok);
    call->WritesDone(reinterpret_cast<void*>(3));
    cq.Next(&tag, &ok);
    grpc::ByteBuffer resp;
    call->Read(&resp, reinterpret_cast<void*>(4));
    cq.Next(&tag, &ok);
    EXPECT_FALSE(ok) << method << ": a malformed request got a message back";
    grpc::Status st;
    call->Finish(&st, reinterpret_cast<void*>(5));
    cq.Next(&tag, &ok);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << method << ": " << st.error_message();
    cq.Shutdown();
    while (cq.Next(&tag, &ok)) {
    }
  }
  expectHealthy(c);
}

TEST(Robustness, AWorkerAnsweringWithTheWrongGradientLengthFailsOnlyItsTask) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  std::atomic<int> answered{0};
  // Three gradient values where the job has thousands, and images nobody asked for.
  ScriptedWorker fake(c.address(), "fake", [&](const v1::Task&, v1::TaskResult& r) {
    for (int k = 0; k < 3; ++k) r.add_gradient(1e6);
    v1::FloatImage* im = r.add_renders();
    im->set_width(100000);
    im->set_height(100000);
    im->set_channels(3);
    ++answered;
    return true;
  });
  waitForWorkers(c, 1);  // connected before the real worker, so it gets a shard
  c.startWorker(1);
  waitForWorkers(c, 2);
  v1::JobSpec job = smallJob("backlit", 3);
  job.mutable_optimization()->set_shards(2);
  job.mutable_optimization()->set_target_spp(2);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_GE(answered.load(), 1);
  EXPECT_TRUE(anyMessage(evs, "malformed result (gradient has 3 values, the job has"));
  // The retry went to the real worker: the numbers are the in-process ones.
  EXPECT_EQ(c.checkpointTheta(id), inProcess(job));
  EXPECT_EQ(c.get(id).state(), v1::SUCCEEDED);
}

TEST(Robustness, AWorkerStalledLongerThanItsLeaseIsNotGivenItBackAndTheJobCompletes) {
  TempDir tmp;
  Cluster c(tmp.path);
  // The heartbeat timeout is long, so only the lease can notice the stall. The lease covers a
  // healthy worker's longest task (building a moved shard's session: its targets at 2 spp, about
  // 1 s on one loaded core) several times over, even under sanitizers.
  const std::string lease = std::to_string(scaledSeconds(6));
  // Final renders at 4 spp: at the default 64 a shard's four views take about 18 s on one
  // loaded core, longer than the lease, and the healthy worker would lose them too.
  c.startServer(0, {"--lease-seconds", lease, "--heartbeat-timeout", "120", "--final-spp", "4"});
  pid_t stalled = c.startWorker(1);
  c.startWorker(1);
  v1::JobSpec job = smallJob("backlit", 6);
  job.mutable_optimization()->set_shards(2);
  job.mutable_optimization()->set_target_spp(2);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id, 0, [&](const v1::ProgressEvent& e) { return e.has_step() && e.step().step() >= 2; });
  kill(stalled, SIGSTOP);
  auto rest = c.watch(id, evs.back().sequence() + 1);
  kill(stalled, SIGCONT);
  evs.insert(evs.end(), rest.begin(), rest.end());
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_TRUE(anyMessage(evs, "expired after " + lease + " s"));
  // Every step once (the moved shard rebuilds its reservoirs with a burn-in of its own, so the
  // numbers are not the uninterrupted run's).
  EXPECT_EQ(stepsOf(evs), (std::vector<uint64_t>{1, 2, 3, 4, 5, 6}));
  // Resumed, the stalled worker proves alive again and the server serves on.
  expectHealthy(c);
}

TEST(Robustness, AWorkerThatHeartbeatsWhileHungGetsNoSecondLease) {
  TempDir tmp;
  Cluster c(tmp.path);
  // As above: several times the longest healthy task (targets at 2 spp).
  const std::string lease = std::to_string(scaledSeconds(6));
  // Final renders at 4 spp: at the default 64 a shard's four views take about 18 s on one
  // loaded core, longer than the lease, and the healthy worker would lose them too. No grace
  // period: both workers are connected before the job is submitted.
  c.startServer(0, {"--lease-seconds", lease, "--heartbeat-timeout", "120", "--final-spp", "4", "--assign-grace", "0"});
  std::atomic<int> received{0};
  // Connected first, so it gets a shard; it never answers, and its heartbeats say it is busy.
  ScriptedWorker hung(
      c.address(), "hung", [&](const v1::Task&, v1::TaskResult&) {
        ++received;
        return false;
      },
      true);
  waitForWorkers(c, 1);
  c.startWorker(1);
  waitForWorkers(c, 2);
  v1::JobSpec job = smallJob("backlit", 3);
  job.mutable_optimization()->set_shards(2);
  job.mutable_optimization()->set_target_spp(2);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_TRUE(anyMessage(evs, "lease on worker hung expired after " + lease + " s"));
  // A second job starts with fresh assignments: the hung worker looks idle to a least-loaded
  // pick, but its heartbeats never showed it free, so it gets no lease here either.
  std::string second;
  ASSERT_TRUE(c.submit(job, &second).ok());
  auto evs2 = c.watch(second);
  ASSERT_TRUE(evs2.back().has_final());
  EXPECT_EQ(evs2.back().final().state(), v1::SUCCEEDED) << evs2.back().final().reason();
  EXPECT_EQ(received.load(), 1);
}

TEST(Robustness, CancelStopsALongTargetRenderOnTheWorkerWithinASecond) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  c.startWorker(2);
  // 65536 samples per pixel: the target render alone would take many minutes.
  v1::JobSpec slow = smallJob("cornell", 2);
  slow.mutable_optimization()->set_target_spp(65536);
  std::string slowId;
  ASSERT_TRUE(c.submit(slow, &slowId).ok());
  c.watch(slowId, 0, [](const v1::ProgressEvent& e) { return e.has_message() && e.message().rfind("started", 0) == 0; });
  std::this_thread::sleep_for(1s);  // the worker is inside the target render now
  const auto cancelledWall = std::chrono::system_clock::now();
  {
    grpc::ClientContext ctx;
    v1::CancelJobRequest req;
    req.set_job_id(slowId);
    v1::JobStatus s;
    ASSERT_TRUE(c.stub().CancelJob(&ctx, req, &s).ok());
  }
  // The next job's first task reaches the same worker only once the render has stopped.
  std::string id;
  ASSERT_TRUE(c.submit(smallJob("cornell", 2), &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  EXPECT_EQ(c.get(slowId).state(), v1::CANCELLED);
  std::ifstream log(c.workerLog(0));
  std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  size_t at = text.find("of " + slowId + " cancelled");
  ASSERT_NE(at, std::string::npos) << text;
  // The worker's log line says when the render stopped: within a second of the cancel, as the
  // service promises (the render it abandoned would have taken many minutes).
  size_t lineStart = text.rfind('\n', at);
  lineStart = lineStart == std::string::npos ? 0 : lineStart + 1;
  std::tm tm{};
  int ms = 0;
  ASSERT_EQ(std::sscanf(text.c_str() + lineStart, "[%d-%d-%d %d:%d:%d.%d]", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
                        &tm.tm_min, &tm.tm_sec, &ms),
            7)
      << text.substr(lineStart, 80);
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  tm.tm_isdst = -1;
  auto stoppedWall = std::chrono::system_clock::from_time_t(std::mktime(&tm)) + std::chrono::milliseconds(ms);
  double delay = std::chrono::duration<double>(stoppedWall - cancelledWall).count();
  EXPECT_LT(delay, 1.0) << text.substr(lineStart, 120);
}

TEST(Robustness, TheJobSpecTravelsOncePerWorkerConnectionAndAgainWhenLost) {
  TempDir tmp;
  Cluster c(tmp.path);
  c.startServer();
  // Answers every task with zeros of the right shape, and once claims to have lost the spec (as
  // after an eviction): it sees how often the spec travels.
  std::mutex mu;
  int tasks = 0, withSpec = 0, specUnknownSent = 0;
  std::map<std::string, std::pair<size_t, std::pair<int, int>>> shapes;  // spec hash -> parameters, film
  ScriptedWorker zero(c.address(), "zero", [&](const v1::Task& t, v1::TaskResult& r) {
    std::lock_guard<std::mutex> lk(mu);
    ++tasks;
    if (t.has_spec()) {
      ++withSpec;
      Problem p = buildProblem(t.spec());
      shapes[t.spec_sha256()] = {p.params.size(), {p.scene->width, p.scene->height}};
    }
    if (tasks == 3 || !shapes.count(t.spec_sha256())) {
      shapes.erase(t.spec_sha256());
      ++specUnknownSent;
      r.set_spec_unknown(true);
      return true;
    }
    auto [n, film] = shapes[t.spec_sha256()];
    if (t.kind() == v1::Task::FINAL_RENDER) {
      for (int k = 0; k < 2 * t.views_size(); ++k) {
        v1::FloatImage* im = r.add_renders();
        im->set_width(film.first);
        im->set_height(film.second);
        im->set_channels(3);
        im->mutable_pixels()->Resize(film.first * film.second * 3, 0.f);
      }
    } else {
      r.mutable_gradient()->Resize(int(n), 0.0);
    }
    return true;
  });
  std::string id;
  ASSERT_TRUE(c.submit(smallJob("cornell", 6), &id).ok());
  auto evs = c.watch(id);
  ASSERT_TRUE(evs.back().has_final());
  EXPECT_EQ(evs.back().final().state(), v1::SUCCEEDED) << evs.back().final().reason();
  std::lock_guard<std::mutex> lk(mu);
  // 2 burn-in + 6 gradient steps + the initial and the final render (+ the one answered
  // spec_unknown, sent again).
  EXPECT_EQ(tasks, 11);
  EXPECT_EQ(specUnknownSent, 1);
  EXPECT_EQ(withSpec, 2);  // the first task, and the retry after spec_unknown
  // A lost spec costs no attempt: nothing failed.
  EXPECT_FALSE(anyMessage(evs, "failed"));
}

int freePort() {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  close(fd);
  return ntohs(a.sin_port);
}

int waitExit(pid_t pid, double seconds) {
  auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int status = 0;
  while (std::chrono::steady_clock::now() < end) {
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(50ms);
  }
  kill(pid, SIGKILL);
  waitpid(pid, &status, 0);
  return -1;  // still running
}

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(Robustness, WatchResumesAcrossAServerRestart) {
  TempDir tmp;
  Cluster c(tmp.path);
  const int port = freePort();
  c.startServer(port);
  c.startWorker(2);
  v1::JobSpec job = smallJob("backlit", 12);
  job.mutable_optimization()->set_shards(1);
  std::string id;
  ASSERT_TRUE(c.submit(job, &id).ok());
  c.watch(id, 0, [](const v1::ProgressEvent& e) { return e.has_step(); });
  pid_t watcher = spawn({(kBin / "invr").string(), "watch", id, "--server", c.address(), "--json", "--reconnect-timeout", "60"},
                        tmp.path / "watch.log");
  std::this_thread::sleep_for(500ms);
  c.killServer();
  const auto down = std::chrono::steady_clock::now();
  // Meanwhile, a watch with a short budget gives up after --reconnect-timeout, saying how to resume.
  pid_t giveUp = spawn({(kBin / "invr").string(), "watch", id, "--server", c.address(), "--from", "3", "--reconnect-timeout", "2"},
                       tmp.path / "giveup.log");
  EXPECT_EQ(waitExit(giveUp, 30), 5);
  std::string said = readFile(tmp.path / "giveup.log");
  EXPECT_NE(said.find("server unavailable for 2 s"), std::string::npos) << said;
  EXPECT_NE(said.find("invr watch " + id + " --from 3"), std::string::npos) << said;
  std::this_thread::sleep_until(down + 12s);  // longer than any retry budget the old client had (about 10 s)
  c.startServer(port);
  int code = waitExit(watcher, 300);
  std::string out = readFile(tmp.path / "watch.log");
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("\"state\":\"SUCCEEDED\""), std::string::npos) << out;
  EXPECT_NE(out.find("server restarted; queued again"), std::string::npos) << out;
  EXPECT_EQ(c.get(id).state(), v1::SUCCEEDED);
}

TEST(Robustness, ASecondServerOnTheSamePortOrStoreExitsWithAClearError) {
  TempDir tmp;
  Cluster c(tmp.path);
  const int port = c.startServer();
  pid_t samePort = spawn({(kBin / "invr-server").string(), "--store", (tmp.path / "other-store").string(), "--address",
                          "127.0.0.1:" + std::to_string(port)},
                         tmp.path / "second.log");
  EXPECT_EQ(waitExit(samePort, 20), 1);
  EXPECT_NE(readFile(tmp.path / "second.log").find("cannot listen on 127.0.0.1:" + std::to_string(port)), std::string::npos)
      << readFile(tmp.path / "second.log");
  pid_t sameStore = spawn({(kBin / "invr-server").string(), "--store", c.store().string(), "--address", "127.0.0.1:0"},
                          tmp.path / "third.log");
  EXPECT_EQ(waitExit(sameStore, 20), 1);
  EXPECT_NE(readFile(tmp.path / "third.log").find("is in use by another invr-server"), std::string::npos)
      << readFile(tmp.path / "third.log");
  c.startWorker(2);
  expectHealthy(c);
}

}  // namespace
}  // namespace invr
