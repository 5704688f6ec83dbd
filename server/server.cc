#include "server/server.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "core/diff/memory_model.h"
#include "core/diff/plan.h"
#include "core/diff/problem.h"
#include "core/error.h"
#include "core/image/image.h"
#include "core/io/job_io.h"
#include "core/io/limits.h"
#include "core/optim/optimization_loop.h"
#include "core/optim/results_io.h"
#include "invr/v1/service.grpc.pb.h"
#include "server/asset_store.h"
#include "server/job_store.h"
#include "proto/wire/sha256.h"
#include "server/task_check.h"
#include "proto/wire/wire.h"

namespace invr::server {

namespace v1 = invr::v1;
using Clock = std::chrono::steady_clock;

namespace {

int64_t unixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

bool finished(v1::JobState s) { return s == v1::SUCCEEDED || s == v1::FAILED || s == v1::CANCELLED; }

const char* stateName(v1::JobState s) { return v1::JobState_Name(s).c_str(); }

struct JobCancelled {};
struct JobFailed {
  std::string reason;
};

// A queue of messages written one at a time on a server stream. Decisions are made under the
// stream's own mutex and Start*/Finish are called after releasing it, so a reaction that runs
// inline cannot deadlock.
template <class Reactor, class Msg>
class WriteQueue {
 public:
  explicit WriteQueue(Reactor* r) : r_(r) {}
  void push(Msg m, bool last = false) {
    const Msg* start = nullptr;
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (closing_) return;
      q_.push_back(std::move(m));
      if (last) closing_ = true, lastQueued_ = true;
      if (writing_) return;
      writing_ = true;
      start = &q_.front();
    }
    r_->StartWrite(start);
  }
  // After a write completes: the next message, or Finish once closing and drained.
  void done(bool ok) {
    const Msg* next = nullptr;
    bool fin = false;
    {
      std::lock_guard<std::mutex> lk(mu_);
      q_.pop_front();
      if (!ok) closing_ = true, q_.clear();
      if (!q_.empty()) {
        next = &q_.front();
      } else {
        writing_ = false;
        if (closing_ && !finished_) finished_ = fin = true;
      }
    }
    if (next) r_->StartWrite(next);
    if (fin) r_->Finish(status_);
  }
  // Stop writing; Finish now if nothing is in flight, else when it completes.
  void close(grpc::Status status = grpc::Status::OK) {
    bool fin = false;
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (!closing_) status_ = status;
      closing_ = true;
      if (!writing_ && !finished_) finished_ = fin = true;
    }
    if (fin) r_->Finish(status_);
  }

 private:
  Reactor* r_;
  std::mutex mu_;
  std::deque<Msg> q_;
  bool writing_ = false, closing_ = false, finished_ = false, lastQueued_ = false;
  grpc::Status status_ = grpc::Status::OK;
};

}  // namespace

// ----------------------------------------------------------------------------------------------

struct Server::Impl final : v1::InvrService::CallbackService, v1::WorkerService::CallbackService {
  class WorkerStream;
  class Watcher;

  struct WorkerEntry {
    uint64_t id = 0;
    std::string name;
    uint32_t capacity = 1;
    WorkerStream* stream = nullptr;  // null once the stream ended
    bool leaving = false;
    Clock::time_point lastSeen;
    // A worker whose lease expired gets no new lease until it proves alive: a heartbeat that is
    // idle or busy with a task whose lease did not expire, or any result.
    bool suspect = false;
    std::set<uint64_t> expiredTasks;
    std::map<std::string, std::string> specsSent;  // job id -> hash of the spec this connection holds
    bool alive() const { return stream != nullptr; }
    bool eligible() const { return alive() && !leaving && !suspect; }
  };

  struct JobEntry {
    v1::JobRecord rec;
    std::vector<v1::ProgressEvent> events;
    uint64_t nextSeq = 1;
    bool cancelRequested = false;
    uint64_t step = 0, steps = 0;
    double loss = std::nan(""), paramError = -1, seconds = 0;
    std::string method;
    std::set<Watcher*> watchers;
  };

  struct Lease {
    uint64_t taskId = 0;
    size_t shard = 0;
    uint64_t worker = 0;
    Clock::time_point deadline;
    bool done = false;
    bool sentSpec = false;  // the task carried the whole spec
    v1::Task task;          // what was asked (without spec and theta): results are checked against it
    ResultShape shape;
    v1::TaskResult result;
  };

  // One running job's scheduling state.
  struct Run {
    std::string id;
    v1::JobSpec spec;
    std::string specHash;
    ResultShape shape;
    std::vector<uint64_t> avoid;       // shard -> worker that last failed it (0: none)
    std::vector<uint64_t> assignment;  // shard -> worker (0: none); sticky
    std::vector<int> attempts;         // failed attempts of the current evaluation, per shard
    uint32_t rebuildBurnIn = 0;
    bool announcedWaiting = false;
    Clock::time_point started = Clock::now();
  };

  ServerOptions opt;
  JobStore jobs;
  AssetStore assets;
  std::unique_ptr<grpc::Server> grpcServer;

  std::mutex mu;
  std::condition_variable cv;
  std::map<std::string, JobEntry> jobTable;
  std::map<std::string, std::string> byRequestId;
  std::deque<std::string> queue;  // queued job ids, in order
  std::map<uint64_t, WorkerEntry> workers;
  std::map<uint64_t, Lease> leases;
  uint64_t nextWorker = 1, nextTask = 1;
  const std::vector<uint64_t>* runAssignment = nullptr;  // the running job's shard -> worker
  // The problem one queued job was validated with, kept for its run so it is built once (the
  // server builds no BVH). One slot: queued jobs beyond it are built again when they start, so
  // a long queue holds no problems in memory.
  std::unique_ptr<Problem> prepared;
  std::string preparedId;
  bool stopping = false;

  // Control work (job validation) runs here, off the gRPC threads.
  std::deque<std::function<void()>> control;
  std::condition_variable controlCv;
  std::thread controlThread, runnerThread;

  int storeLock = -1;  // flock on <store>/LOCK while this server runs
  ~Impl() {
    if (storeLock >= 0) ::close(storeLock);
  }

  explicit Impl(ServerOptions o) : opt(std::move(o)), jobs(opt.storeDir / "jobs"), assets(opt.storeDir / "assets") {}

  // ------------------------------------------------------------------ streams

  class WorkerStream final : public grpc::ServerBidiReactor<v1::WorkerMessage, v1::ServerMessage> {
   public:
    explicit WorkerStream(Impl* s) : s_(s), out_(this) { StartRead(&in_); }
    void send(v1::ServerMessage m) { out_.push(std::move(m)); }
    void close() { out_.close(); }
    void OnReadDone(bool ok) override {
      if (!ok) {
        s_->workerGone(this);
        out_.close();
        return;
      }
      s_->onWorkerMessage(this, in_);
      StartRead(&in_);
    }
    void OnWriteDone(bool ok) override { out_.done(ok); }
    void OnCancel() override { out_.close(); }
    void OnDone() override {
      s_->workerGone(this);
      delete this;
    }

   private:
    Impl* s_;
    v1::WorkerMessage in_;
    WriteQueue<WorkerStream, v1::ServerMessage> out_;
  };

  class Watcher final : public grpc::ServerWriteReactor<v1::ProgressEvent> {
   public:
    Watcher(Impl* s, std::string job) : s_(s), job_(std::move(job)), out_(this) {}
    void push(const v1::ProgressEvent& e) { out_.push(e, e.has_final()); }
    void close(grpc::Status st) { out_.close(st); }
    void OnWriteDone(bool ok) override { out_.done(ok); }
    void OnCancel() override { out_.close(grpc::Status::CANCELLED); }
    void OnDone() override {
      s_->removeWatcher(job_, this);
      delete this;
    }

   private:
    Impl* s_;
    std::string job_;
    WriteQueue<Watcher, v1::ProgressEvent> out_;
  };

  // Streams a file in chunks (results to clients, assets to workers).
  class FileSender final : public grpc::ServerWriteReactor<v1::AssetChunk> {
   public:
    explicit FileSender(const std::filesystem::path& path) : in_(path, std::ios::binary) {
      if (!in_) {
        Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "cannot read '" + path.filename().string() + "'"));
        return;
      }
      next();
    }
    void OnWriteDone(bool ok) override {
      if (!ok) return Finish(grpc::Status::CANCELLED);
      next();
    }
    void OnDone() override { delete this; }

   private:
    void next() {
      std::string buf(wire::kChunkBytes, '\0');
      in_.read(buf.data(), std::streamsize(buf.size()));
      buf.resize(size_t(in_.gcount()));
      if (buf.empty() && sent_) return Finish(grpc::Status::OK);
      sent_ = true;  // an empty file still sends one (empty) chunk
      chunk_.set_data(std::move(buf));
      StartWrite(&chunk_);
    }
    std::ifstream in_;
    v1::AssetChunk chunk_;
    bool sent_ = false;
  };

  class Uploader final : public grpc::ServerReadReactor<v1::AssetChunk> {
   public:
    Uploader(Impl* s, v1::AssetInfo* info) : info_(info), up_(s->assets, s->opt.maxAssetBytes), max_(s->opt.maxAssetBytes) {
      StartRead(&chunk_);
    }
    void OnReadDone(bool ok) override {
      if (ok) {
        if (!up_.append(chunk_.data()))
          return Finish(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                     "upload: larger than the server's limit of " + std::to_string(max_) + " bytes"));
        return StartRead(&chunk_);
      }
      try {
        info_->set_size(up_.size());
        info_->set_sha256(up_.commit());
        Finish(grpc::Status::OK);
      } catch (const std::exception& e) {
        Finish(grpc::Status(grpc::StatusCode::INTERNAL, e.what()));
      }
    }
    void OnDone() override { delete this; }

   private:
    v1::AssetInfo* info_;
    v1::AssetChunk chunk_;
    AssetStore::Upload up_;
    uint64_t max_;
  };

  // ------------------------------------------------------------------ client service

  grpc::ServerReadReactor<v1::AssetChunk>* UploadAsset(grpc::CallbackServerContext*, v1::AssetInfo* info) override {
    return new Uploader(this, info);
  }

  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx, const v1::SubmitJobRequest* req,
                                      v1::SubmitJobResponse* resp) override {
    auto* reactor = ctx->DefaultReactor();
    if (req->request_id().size() > 256) {  // it is stored with the job and kept in memory
      reactor->Finish(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                   "request_id: " + std::to_string(req->request_id().size()) + " bytes long (limit 256)"));
      return reactor;
    }
    {
      std::lock_guard<std::mutex> lk(mu);
      if (!req->request_id().empty()) {
        auto it = byRequestId.find(req->request_id());
        if (it != byRequestId.end()) {  // a retry: the same job, not a second one
          resp->set_job_id(it->second);
          resp->set_existing(true);
          reactor->Finish(grpc::Status::OK);
          return reactor;
        }
      }
      if (int(queue.size()) >= opt.maxQueued) {
        reactor->Finish(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                     "queue full: " + std::to_string(queue.size()) + " jobs waiting (limit " +
                                         std::to_string(opt.maxQueued) + "); retry later"));
        return reactor;
      }
    }
    // Building the problem loads meshes and textures: not on a gRPC thread.
    postControl([this, reactor, req, resp] {
      grpc::Status st;
      try {
        st = submit(*req, *resp);
      } catch (const std::exception& e) {  // the store's disk, not the job: say so, keep serving
        st = grpc::Status(grpc::StatusCode::INTERNAL, std::string("job store: ") + e.what());
      }
      reactor->Finish(st);
    });
    return reactor;
  }

  grpc::ServerUnaryReactor* PlanJob(grpc::CallbackServerContext* ctx, const v1::PlanJobRequest* req, v1::JobPlan* resp) override {
    auto* reactor = ctx->DefaultReactor();
    // Building the problem loads meshes and textures: not on a gRPC thread.
    postControl([this, reactor, req, resp] {
      v1::JobSpec spec = req->spec();
      grpc::Status st;
      try {
        st = admit(spec, resp);
      } catch (const std::exception& e) {
        st = grpc::Status(grpc::StatusCode::INTERNAL, e.what());
      }
      reactor->Finish(st);
    });
    return reactor;
  }

  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req, v1::JobStatus* resp) override {
    auto* reactor = ctx->DefaultReactor();
    std::lock_guard<std::mutex> lk(mu);
    auto it = jobTable.find(req->job_id());
    if (it == jobTable.end()) {
      reactor->Finish(notFound(req->job_id()));
    } else {
      *resp = status(it->second);
      reactor->Finish(grpc::Status::OK);
    }
    return reactor;
  }

  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*, v1::ListJobsResponse* resp) override {
    std::lock_guard<std::mutex> lk(mu);
    for (auto& [id, j] : jobTable) *resp->add_jobs() = status(j);
    auto* reactor = ctx->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx, const v1::CancelJobRequest* req, v1::JobStatus* resp) override {
    auto* reactor = ctx->DefaultReactor();
    std::unique_lock<std::mutex> lk(mu);
    auto it = jobTable.find(req->job_id());
    if (it == jobTable.end()) {
      reactor->Finish(notFound(req->job_id()));
      return reactor;
    }
    JobEntry& j = it->second;
    if (j.rec.state() == v1::QUEUED) {
      // Not started: nothing runs, so it ends here (the store write is one small file).
      queue.erase(std::remove(queue.begin(), queue.end(), j.rec.job_id()), queue.end());
      if (preparedId == j.rec.job_id()) prepared.reset();
      j.rec.set_reason("cancelled before it started");
      endJobLocked(j, v1::CANCELLED);
    } else if (j.rec.state() == v1::RUNNING && !j.cancelRequested) {
      j.cancelRequested = true;  // the runner stops the job and its in-flight tasks
      logEventLocked(j, "cancel requested");
      cv.notify_all();
    }
    *resp = status(j);  // idempotent: cancelling a finished job reports its state
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerWriteReactor<v1::ProgressEvent>* WatchJob(grpc::CallbackServerContext*, const v1::WatchJobRequest* req) override {
    auto* w = new Watcher(this, req->job_id());
    std::lock_guard<std::mutex> lk(mu);
    auto it = jobTable.find(req->job_id());
    if (it == jobTable.end()) {
      w->close(notFound(req->job_id()));
      return w;
    }
    JobEntry& j = it->second;
    j.watchers.insert(w);
    bool sentFinal = false;
    for (const auto& e : j.events)
      if (e.sequence() >= req->from_sequence()) {
        w->push(e);
        sentFinal = sentFinal || e.has_final();
      }
    if (finished(j.rec.state()) && !sentFinal) w->close(grpc::Status::OK);  // resumed past the end
    return w;
  }

  grpc::ServerWriteReactor<v1::AssetChunk>* FetchResult(grpc::CallbackServerContext*, const v1::FetchResultRequest* req) override {
    std::filesystem::path path;
    grpc::Status st;
    {
      std::lock_guard<std::mutex> lk(mu);
      auto it = jobTable.find(req->job_id());
      if (it == jobTable.end()) {
        st = notFound(req->job_id());
      } else {
        const auto& res = it->second.rec.results();
        if (std::find(res.begin(), res.end(), req->name()) == res.end())
          st = grpc::Status(grpc::StatusCode::NOT_FOUND, "job " + req->job_id() + " has no result '" + req->name().substr(0, 256) + "'");
        else
          path = jobs.resultsDir(req->job_id()) / req->name();
      }
    }
    if (!st.ok()) {
      struct Failed final : grpc::ServerWriteReactor<v1::AssetChunk> {
        explicit Failed(grpc::Status s) { Finish(s); }
        void OnDone() override { delete this; }
      };
      return new Failed(st);
    }
    return new FileSender(path);
  }

  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* ctx, const v1::ListWorkersRequest*, v1::ListWorkersResponse* resp) override {
    std::lock_guard<std::mutex> lk(mu);
    for (auto& [id, w] : workers) {
      if (!w.alive()) continue;
      auto* ws = resp->add_workers();
      ws->set_name(w.name);
      ws->set_capacity(w.capacity);
      ws->set_leaving(w.leaving);
      ws->set_shards(uint32_t(runAssignment ? std::count(runAssignment->begin(), runAssignment->end(), id) : 0));
    }
    auto* reactor = ctx->DefaultReactor();
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  // ------------------------------------------------------------------ worker service

  grpc::ServerBidiReactor<v1::WorkerMessage, v1::ServerMessage>* Connect(grpc::CallbackServerContext*) override {
    return new WorkerStream(this);
  }

  grpc::ServerWriteReactor<v1::AssetChunk>* FetchAsset(grpc::CallbackServerContext*, const v1::FetchAssetRequest* req) override {
    if (!assets.has(req->sha256())) {
      struct Failed final : grpc::ServerWriteReactor<v1::AssetChunk> {
        explicit Failed(const std::string& h) { Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "no asset " + h.substr(0, 64))); }
        void OnDone() override { delete this; }
      };
      return new Failed(req->sha256());
    }
    return new FileSender(assets.path(req->sha256()));
  }

  void onWorkerMessage(WorkerStream* ws, const v1::WorkerMessage& m) {
    std::lock_guard<std::mutex> lk(mu);
    WorkerEntry* w = nullptr;
    for (auto& [id, e] : workers)
      if (e.stream == ws) w = &e;
    if (m.has_hello()) {
      if (w) return;
      WorkerEntry e;
      e.id = nextWorker++;
      // A name is for logs and `invr workers`: bounded, printable.
      std::string name = m.hello().name().substr(0, 128);
      for (char& c : name)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
      e.name = name.empty() ? "worker-" + std::to_string(e.id) : name;
      e.capacity = std::clamp<uint32_t>(m.hello().capacity(), 1, 4096);
      e.stream = ws;
      e.lastSeen = Clock::now();
      workers[e.id] = e;
      spdlog::info("worker {} ({}, {} threads) connected", e.id, e.name, e.capacity);
      v1::ServerMessage welcome;
      welcome.set_welcome(std::to_string(e.id));
      ws->send(std::move(welcome));
      cv.notify_all();
      return;
    }
    if (!w) return;  // nothing before hello
    w->lastSeen = Clock::now();
    if (m.has_leaving()) {
      w->leaving = true;
      spdlog::info("worker {} ({}) is leaving", w->id, w->name);
    } else if (m.has_heartbeat()) {
      if (w->suspect && !w->expiredTasks.count(m.heartbeat().busy_task())) {
        w->suspect = false;
        w->expiredTasks.clear();
        spdlog::info("worker {} ({}) is alive again after its lease expired", w->id, w->name);
      }
    } else if (m.has_result()) {
      if (w->suspect) {  // it finished (or gave up) an expired task: alive, and free
        w->suspect = false;
        w->expiredTasks.clear();
        spdlog::info("worker {} ({}) is alive again after its lease expired", w->id, w->name);
      }
      auto it = leases.find(m.result().task_id());
      // Exactly once: only the current lease's worker can complete it, and only once.
      if (it == leases.end() || it->second.worker != w->id || it->second.done) {
        spdlog::debug("worker {}: stale result for task {} ignored", w->id, m.result().task_id());
        return;
      }
      Lease& l = it->second;
      std::string bad = checkTaskResult(l.task, m.result(), l.shape);
      if (bad.empty()) {
        l.result = m.result();
      } else {  // the task fails (and is retried elsewhere); nothing of the result is used
        spdlog::warn("worker {} ({}): malformed result for task {}: {}", w->id, w->name, l.taskId, bad);
        l.result = v1::TaskResult();
        l.result.set_error("malformed result (" + bad + ")");
      }
      l.done = true;
    }
    cv.notify_all();
  }

  void workerGone(WorkerStream* ws) {
    std::lock_guard<std::mutex> lk(mu);
    for (auto& [id, e] : workers)
      if (e.stream == ws) {
        e.stream = nullptr;
        spdlog::warn("worker {} ({}) disconnected", e.id, e.name);
      }
    cv.notify_all();
  }

  void removeWatcher(const std::string& job, Watcher* w) {
    std::lock_guard<std::mutex> lk(mu);
    auto it = jobTable.find(job);
    if (it != jobTable.end()) it->second.watchers.erase(w);
  }

  // ------------------------------------------------------------------ jobs

  // Threads of the largest connected worker (the machine's own when none is connected yet).
  unsigned maxWorkerThreads() {
    std::lock_guard<std::mutex> lk(mu);
    unsigned n = 0;
    for (auto& [id, w] : workers)
      if (w.alive()) n = std::max(n, w.capacity);
    return n ? n : std::max(1u, std::thread::hardware_concurrency());
  }

  static grpc::Status notFound(const std::string& id) {
    // The id is the caller's: echo a bounded part of it.
    return grpc::Status(grpc::StatusCode::NOT_FOUND, "no job '" + id.substr(0, 64) + (id.size() > 64 ? "...'" : "'"));
  }

  v1::JobStatus status(const JobEntry& j) const {
    v1::JobStatus s;
    s.set_job_id(j.rec.job_id());
    s.set_name(j.rec.spec().name());
    s.set_state(j.rec.state());
    s.set_reason(j.rec.reason());
    s.set_step(j.step);
    s.set_steps(j.steps);
    s.set_loss(j.loss);
    s.set_param_error(j.paramError);
    s.set_seconds(j.seconds);
    s.set_method(j.method);
    *s.mutable_results() = j.rec.results();
    s.set_last_sequence(j.nextSeq - 1);
    s.set_submitted_unix(j.rec.submitted_unix());
    return s;
  }

  void postControl(std::function<void()> fn) {
    {
      std::lock_guard<std::mutex> lk(mu);
      control.push_back(std::move(fn));
    }
    controlCv.notify_one();
  }

  void controlLoop() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock<std::mutex> lk(mu);
        controlCv.wait(lk, [&] { return stopping || !control.empty(); });
        if (control.empty()) return;
        fn = std::move(control.front());
        control.pop_front();
      }
      fn();
    }
  }

  AssetResolver resolver(MemoryBudget* budget = nullptr) {
    AssetResolver r;
    r.budget = budget;
    r.byHash = [this](const std::string& h) -> std::filesystem::path {
      if (!assets.has(h)) throw InputError("asset " + h + " was not uploaded");
      return assets.path(h);
    };
    return r;
  }

  // Everything a job must pass before it is queued (SubmitJob) or planned (PlanJob): the same
  // checks, errors and codes for both. `plan` (optional) receives the job's plan.
  grpc::Status admit(v1::JobSpec& spec, v1::JobPlan* plan, std::unique_ptr<Problem>* keep = nullptr) {
    // Fields this server does not know would be stored and sent to every worker unread.
    spec.DiscardUnknownFields();
    try {
      validateJobSpec(spec);  // bounds first: nothing below echoes an unbounded string
    } catch (const InputError& e) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
    }
    // A server job may only name built-in scenes and uploaded assets: paths on the client's disk
    // mean nothing here (`invr submit` uploads them and rewrites the references).
    std::optional<grpc::Status> bad;
    forEachAssetRef(spec, [&](v1::AssetRef& ref, const std::string& field) {
      if (bad) return;
      if (ref.source_case() == v1::AssetRef::SOURCE_NOT_SET) return;  // optional (a view without a mask); required ones fail below
      if (ref.has_path())
        bad = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                           field + ".path: a job on a server references assets by sha256 (upload '" + ref.path() + "' first)");
      else if (!AssetStore::validHash(ref.sha256()))
        bad = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, field + ".sha256: '" + ref.sha256() + "' is not a SHA-256 hex digest");
      else if (!assets.has(ref.sha256()))
        bad = grpc::Status(grpc::StatusCode::NOT_FOUND, field + ".sha256: asset " + ref.sha256() + " was not uploaded");
    });
    if (bad) return *bad;
    if (!spec.has_optimization() || spec.optimization().parameters_size() == 0)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "optimization.parameters: a job needs at least one parameter to recover");
    try {
      // Every texture, mesh and target is charged to the job's budget before it is allocated;
      // the problem is dropped again once validated.
      MemoryBudget budget(opt.maxJobBytes);
      Problem p = buildProblem(spec, resolver(&budget), SceneUse::Validate);
      const unsigned threads = maxWorkerThreads();
      WorkerMemory mem = estimateWorkerMemory(p, threads);
      if (plan) *plan = planJob(spec, p, threads);
      if (keep) *keep = std::make_unique<Problem>(std::move(p));
      const double state = mem.images + mem.reservoirs + mem.gradients + mem.textures;  // may exceed 2^64: compare as double
      budget.charge(state < double(budget.limit()) ? uint64_t(state) : budget.limit() + 1,
                    "per-worker state (images, reservoirs, gradients of the largest shard, as `invr plan` estimates it)");
    } catch (const ResourceError& e) {
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, e.what());
    } catch (const InputError& e) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
    } catch (const std::bad_alloc&) {
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "the job does not fit in the server's memory");
    } catch (const std::exception& e) {
      return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
    }
    return grpc::Status::OK;
  }

  grpc::Status submit(const v1::SubmitJobRequest& req, v1::SubmitJobResponse& resp) {
    v1::JobSpec spec = req.spec();
    std::unique_ptr<Problem> validated;
    if (grpc::Status st = admit(spec, nullptr, &validated); !st.ok()) return st;
    std::lock_guard<std::mutex> lk(mu);
    if (!req.request_id().empty()) {  // a concurrent retry may have won the race
      auto it = byRequestId.find(req.request_id());
      if (it != byRequestId.end()) {
        resp.set_job_id(it->second);
        resp.set_existing(true);
        return grpc::Status::OK;
      }
    }
    if (int(queue.size()) >= opt.maxQueued)
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "queue full (limit " + std::to_string(opt.maxQueued) + "); retry later");
    JobEntry j;
    j.rec.set_job_id(jobs.newJobId());
    j.rec.set_request_id(req.request_id());
    *j.rec.mutable_spec() = spec;
    j.rec.set_state(v1::QUEUED);
    j.rec.set_submitted_unix(unixMs() / 1000);
    try {
      jobs.saveRecord(j.rec);
    } catch (const std::exception& e) {
      return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
    }
    std::string id = j.rec.job_id();
    if (!req.request_id().empty()) byRequestId[req.request_id()] = id;
    auto& entry = jobTable[id] = std::move(j);
    queue.push_back(id);
    if (!prepared) {
      prepared = std::move(validated);
      preparedId = id;
    }
    logEventLocked(entry, "queued (" + std::to_string(queue.size()) + " in queue)");
    spdlog::info("[{}] submitted: {}", id, spec.name());
    resp.set_job_id(id);
    cv.notify_all();
    return grpc::Status::OK;
  }

  void publishLocked(JobEntry& j, v1::ProgressEvent ev) {
    ev.set_sequence(j.nextSeq++);
    ev.set_unix_ms(unixMs());
    jobs.appendEvent(j.rec.job_id(), ev);
    for (Watcher* w : j.watchers) w->push(ev);
    j.events.push_back(std::move(ev));
  }

  void logEventLocked(JobEntry& j, const std::string& message) {
    v1::ProgressEvent ev;
    ev.set_message(message);
    spdlog::info("[{} step {}] {}", j.rec.job_id(), j.step, message);
    publishLocked(j, std::move(ev));
  }

  void endJobLocked(JobEntry& j, v1::JobState state) {
    j.rec.set_state(state);
    try {
      jobs.saveRecord(j.rec);
    } catch (const std::exception& e) {
      spdlog::error("[{}] cannot save its record: {}", j.rec.job_id(), e.what());
    }
    spdlog::info("[{} step {}] {}{}{}", j.rec.job_id(), j.step, stateName(state), j.rec.reason().empty() ? "" : ": ", j.rec.reason());
    v1::ProgressEvent ev;
    *ev.mutable_final() = status(j);
    publishLocked(j, std::move(ev));
    // Every watcher gets the final event; release workers' sessions (and specs) for this job.
    for (auto& [id, w] : workers) {
      w.specsSent.erase(j.rec.job_id());
      if (w.stream) {
        v1::ServerMessage m;
        m.set_release_job(j.rec.job_id());
        w.stream->send(std::move(m));
      }
    }
    cv.notify_all();
  }

  void logEvent(const std::string& job, const std::string& message) {
    std::lock_guard<std::mutex> lk(mu);
    logEventLocked(jobTable.at(job), message);
  }

  // ------------------------------------------------------------------ scheduling

  // A live worker for the shard: its sticky one if still there, else the least loaded eligible
  // one, preferring any worker but the one that last failed the shard.
  uint64_t pickWorkerLocked(Run& run, JobEntry& job, size_t shard) {
    uint64_t w = run.assignment[shard];
    if (w && workers.count(w) && workers[w].alive() && !workers[w].suspect) return w;
    if (w) {  // its worker vanished (or stalled) between steps
      logEventLocked(job, "shard " + std::to_string(shard) + ": worker " + workers[w].name +
                              (workers[w].alive() ? " unresponsive" : " lost") + "; reassigning");
      run.assignment[shard] = 0;
    }
    uint64_t best = 0;
    std::pair<bool, size_t> bestKey{true, SIZE_MAX};  // (is the avoided worker, load)
    for (auto& [id, e] : workers) {
      if (!e.eligible()) continue;
      std::pair<bool, size_t> key{id == run.avoid[shard], size_t(std::count(run.assignment.begin(), run.assignment.end(), id))};
      if (!best || key < bestKey) best = id, bestKey = key;
    }
    if (best) {
      run.assignment[shard] = best;
      if (w) logEventLocked(job, "shard " + std::to_string(shard) + " moved to worker " + workers[best].name + " (rebuilding its state)");
    }
    return best;
  }

  void checkWorkersLocked() {
    auto now = Clock::now();
    for (auto& [id, e] : workers)
      if (e.alive() && std::chrono::duration<double>(now - e.lastSeen).count() > opt.heartbeatTimeoutSeconds) {
        spdlog::warn("worker {} ({}) silent for {:.0f} s: presumed gone", id, e.name, opt.heartbeatTimeoutSeconds);
        WorkerStream* ws = e.stream;
        e.stream = nullptr;
        ws->close();
      }
  }

  // Sends each shard's task to its worker and waits for every result, reassigning leases whose
  // worker vanished or whose deadline passed. Returns results in shard order.
  std::vector<std::optional<v1::TaskResult>> dispatch(Run& run, std::vector<std::optional<v1::Task>>& tasks) {
    size_t n = tasks.size();
    std::vector<std::optional<v1::TaskResult>> results(n);
    std::vector<uint64_t> leaseOf(n, 0);
    std::fill(run.attempts.begin(), run.attempts.end(), 0);
    std::unique_lock<std::mutex> lk(mu);
    JobEntry& job = jobTable.at(run.id);
    auto dropLease = [&](size_t s) {
      leases.erase(leaseOf[s]);
      leaseOf[s] = 0;
    };
    auto retry = [&](size_t s, const std::string& why) {
      logEventLocked(job, "shard " + std::to_string(s) + ": " + why + "; reassigning");
      if (leaseOf[s]) run.avoid[s] = leases[leaseOf[s]].worker;
      run.assignment[s] = 0;
      dropLease(s);
      if (++run.attempts[s] >= opt.maxAttempts)
        throw JobFailed{"shard " + std::to_string(s) + " failed " + std::to_string(run.attempts[s]) + " times (last: " + why + ")"};
    };
    try {
      for (;;) {
        if (stopping) throw JobCancelled{};
        if (job.cancelRequested) throw JobCancelled{};
        checkWorkersLocked();
        bool waiting = false;
        // Shards stick to the workers they start on, so a job that has more shards than
        // connected workers gives late workers (starting up, reconnecting after a server
        // restart) a moment before the first assignment.
        bool unassigned = std::all_of(run.assignment.begin(), run.assignment.end(), [](uint64_t w) { return w == 0; });
        size_t alive = size_t(std::count_if(workers.begin(), workers.end(), [](const auto& kv) { return kv.second.eligible(); }));
        bool settle = unassigned && alive > 0 && alive < run.assignment.size() &&
                      std::chrono::duration<double>(Clock::now() - run.started).count() < opt.assignGraceSeconds;
        for (size_t s = 0; s < n && !settle; ++s) {
          if (!tasks[s] || results[s] || leaseOf[s]) continue;
          uint64_t w = pickWorkerLocked(run, job, s);
          if (!w) {
            waiting = true;
            continue;
          }
          v1::Task t = *tasks[s];
          t.set_task_id(nextTask++);
          // Whenever a worker (re)builds the shard's session mid-job (new assignment, eviction,
          // restart) it refills the reservoirs with this many render-only steps first.
          t.set_rebuild_burn_in(run.rebuildBurnIn);
          t.set_spec_sha256(run.specHash);
          Lease l;
          l.taskId = t.task_id();
          l.shard = s;
          l.worker = w;
          l.deadline = Clock::now() + std::chrono::milliseconds(int64_t(opt.leaseSeconds * 1000));
          // What the result is checked against (not θ: a texture's θ is megabytes).
          l.task.set_task_id(t.task_id());
          l.task.set_job_id(t.job_id());
          l.task.set_kind(t.kind());
          l.task.set_shard(t.shard());
          *l.task.mutable_views() = t.views();
          l.task.set_render_only(t.render_only());
          l.shape = run.shape;
          // The spec travels once per worker connection; later tasks name it by hash.
          WorkerEntry& we = workers[w];
          if (auto [it, fresh] = we.specsSent.try_emplace(run.id, run.specHash); fresh || it->second != run.specHash) {
            it->second = run.specHash;
            *t.mutable_spec() = run.spec;
            l.sentSpec = true;
          }
          leases[l.taskId] = std::move(l);
          leaseOf[s] = t.task_id();
          v1::ServerMessage m;
          *m.mutable_task() = std::move(t);
          we.stream->send(std::move(m));
        }
        if (waiting && !run.announcedWaiting) {
          bool stalled = std::any_of(workers.begin(), workers.end(), [](const auto& kv) { return kv.second.alive() && kv.second.suspect; });
          logEventLocked(job, stalled ? "waiting for an unresponsive worker to recover or another to connect" : "waiting for a worker to connect");
        }
        run.announcedWaiting = waiting;
        bool all = true;
        for (size_t s = 0; s < n; ++s) {
          if (!tasks[s] || results[s]) continue;
          if (!leaseOf[s]) {
            all = false;
            continue;
          }
          Lease& l = leases[leaseOf[s]];
          const WorkerEntry& w = workers[l.worker];
          if (l.done && l.result.spec_unknown() && !l.sentSpec) {
            // The worker lost the spec (it reconnected or dropped it): send it again, no attempt lost.
            workers[l.worker].specsSent.erase(run.id);
            dropLease(s);
            all = false;
            continue;
          }
          if (l.done) {
            if (l.result.error().empty() && !l.result.spec_unknown()) {
              results[s] = std::move(l.result);
              dropLease(s);
              continue;
            }
            all = false;
            if (l.result.input_error()) {
              throw JobFailed{l.result.error()};
            } else {
              retry(s, "worker " + w.name + " failed: " +
                           (l.result.spec_unknown() ? std::string("it did not take the job's spec") : l.result.error()));
            }
          } else if (!w.alive()) {
            all = false;
            retry(s, "worker " + w.name + " lost");
          } else {
            all = false;
            if (Clock::now() > l.deadline) {
              WorkerEntry& stalled = workers[l.worker];
              stalled.suspect = true;
              stalled.expiredTasks.insert(l.taskId);
              retry(s, "lease on worker " + w.name + " expired after " + fmtSeconds(opt.leaseSeconds) +
                           " (no new lease for it until it shows it is alive)");
            }
          }
        }
        if (all) return results;
        cv.wait_for(lk, std::chrono::milliseconds(settle ? 20 : 100));
      }
    } catch (...) {
      for (size_t s = 0; s < n; ++s)
        if (leaseOf[s]) leases.erase(leaseOf[s]);
      throw;
    }
  }

  // The spec is added per worker at dispatch (once per connection).
  v1::Task baseTask(const Run& run, size_t shard, const std::vector<float>& theta) {
    v1::Task t;
    t.set_job_id(run.id);
    t.set_shard(uint32_t(shard));
    t.mutable_theta()->Assign(theta.begin(), theta.end());
    return t;
  }

  static std::string fmtSeconds(double s) {
    char b[32];
    std::snprintf(b, sizeof b, "%g s", s);
    return b;
  }

  void runnerLoop() {
    for (;;) {
      std::string id;
      {
        std::unique_lock<std::mutex> lk(mu);
        cv.wait(lk, [&] { return stopping || !queue.empty(); });
        if (stopping) return;
        id = queue.front();
        queue.pop_front();
      }
      try {
        runJob(id);
      } catch (const std::exception& e) {  // only the store's disk can get here; the server stays up
        spdlog::error("[{}] {}", id, e.what());
      }
    }
  }

  void runJob(const std::string& id) {
    v1::JobSpec spec;
    {
      std::lock_guard<std::mutex> lk(mu);
      JobEntry& j = jobTable.at(id);
      spec = j.rec.spec();
      j.rec.set_state(v1::RUNNING);
      jobs.saveRecord(j.rec);
    }
    Problem p;
    std::vector<float> theta;
    v1::Checkpoint ck;
    bool haveCheckpoint = false;
    std::vector<std::string> csv;
    std::string method;
    try {
      std::unique_ptr<Problem> validated;
      {
        std::lock_guard<std::mutex> lk(mu);
        if (prepared && preparedId == id) validated = std::move(prepared);
      }
      if (validated) {
        p = std::move(*validated);  // built when it was submitted
      } else {
        MemoryBudget budget(opt.maxJobBytes);
        p = buildProblem(spec, resolver(&budget), SceneUse::Validate);  // the server never traces a ray
      }
      method = gradientMethodName(p.gradient.method);
      auto saved = jobs.loadCheckpoint(id);
      haveCheckpoint = saved.has_value();
      OptimizerState state;
      uint64_t counter = 0, step = 0;
      double secondsBefore = 0;
      if (saved) {
        ck = *saved;
        theta.assign(ck.theta().begin(), ck.theta().end());
        state.m.assign(ck.adam_m().begin(), ck.adam_m().end());
        state.v.assign(ck.adam_v().begin(), ck.adam_v().end());
        state.step = ck.optimizer_step();
        counter = ck.counter();
        step = ck.step();
        secondsBefore = ck.seconds();
      } else {
        // Step 0 is a checkpoint too: a job that diverges on its first step still has one to keep.
        theta = p.initial;
        ck.set_step(0);
        ck.set_counter(0);
        ck.mutable_theta()->Assign(theta.begin(), theta.end());
        jobs.saveCheckpoint(id, ck);
        haveCheckpoint = true;
      }
      if (theta.size() != p.params.size()) throw JobFailed{"checkpoint does not match the job's parameters"};
      Run run;
      run.id = id;
      run.spec = spec;
      {
        std::string bytes;
        {
          google::protobuf::io::StringOutputStream raw(&bytes);
          google::protobuf::io::CodedOutputStream coded(&raw);
          coded.SetSerializationDeterministic(true);
          spec.SerializeToCodedStream(&coded);
        }
        Sha256 h;
        h.update(bytes.data(), bytes.size());
        run.specHash = h.hex();
      }
      run.shape.parameters = p.params.size();
      run.shape.width = p.scene->width;
      run.shape.height = p.scene->height;
      run.avoid.assign(p.shards.size(), 0);
      run.assignment.assign(p.shards.size(), 0);
      run.attempts.assign(p.shards.size(), 0);
      // A worker that takes over a shard mid-job rebuilds its reservoirs with render-only steps.
      {
        std::lock_guard<std::mutex> lk(mu);
        runAssignment = &run.assignment;
      }
      struct Unpublish {
        Impl* s;
        ~Unpublish() {
          std::lock_guard<std::mutex> lk(s->mu);
          s->runAssignment = nullptr;
        }
      } unpublish{this};
      run.rebuildBurnIn = p.gradient.method == GradientMethod::Restir ? uint32_t(std::max(p.burnIn, 1)) : 0;
      {
        std::lock_guard<std::mutex> lk(mu);
        JobEntry& j = jobTable.at(id);
        j.steps = uint64_t(p.steps);
        j.step = step;
        j.method = method;
        std::ostringstream msg;
        if (saved)
          msg << "resumed from checkpoint at step " << step << "/" << p.steps;
        else
          msg << "started: " << p.params.size() << " parameter values, " << p.steps << " steps, method " << method << ", "
              << p.scene->cameras.size() << " views in " << p.shards.size() << " shards";
        logEventLocked(j, msg.str());
      }
      LoopState start;
      start.theta = theta;
      start.optimizer = state;
      start.counter = counter;
      start.step = step;
      OptimizationLoop loop(p, std::move(start), p.burnIn, p.steps);
      auto runStart = Clock::now();
      uint64_t stepsThisRun = 0;
      Clock::time_point firstStepDone = runStart;
      // The shards go to workers; the loop sums their results in shard order, as in process.
      double wall = 0, slowest = 0;
      auto evaluateOnWorkers = [&](const Evaluation& e, const std::vector<float>& at) {
        std::vector<std::optional<v1::Task>> tasks(p.shards.size());
        for (size_t s = 0; s < p.shards.size(); ++s) {
          GradientRequest r = shardRequest(p, e, s);
          if (r.views.empty()) continue;
          v1::Task t = baseTask(run, s, at);
          t.set_kind(v1::Task::GRADIENT);
          t.mutable_views()->Assign(r.views.begin(), r.views.end());
          t.set_batch_views(uint32_t(r.batchViews));
          t.set_all_shard_views(r.allSessionViews);
          t.set_counter(e.counter);
          t.set_render_only(e.renderOnly);
          tasks[s] = std::move(t);
        }
        auto t0 = Clock::now();
        auto results = dispatch(run, tasks);
        wall = std::chrono::duration<double>(Clock::now() - t0).count();
        slowest = 0;
        std::vector<std::optional<GradientResult>> out(results.size());
        for (size_t s = 0; s < results.size(); ++s) {
          const auto& r = results[s];
          if (!r) continue;
          GradientResult g;
          g.gradient.assign(r->gradient().begin(), r->gradient().end());
          g.stats.loss = r->loss();
          g.stats.nonFiniteSamples = r->non_finite();
          g.stats.secondsPrimal = r->seconds_primal();
          g.stats.secondsDerivative = r->seconds_derivative();
          g.stats.secondsReservoirUpdate = r->seconds_reservoir();
          g.stats.secondsStage1 = r->seconds_stage1();
          g.stats.biasTerm = r->bias_term();
          g.stats.varianceTerm = r->variance_term();
          g.stats.cost = r->cost();
          g.stats.secondsVariance = r->seconds_variance();
          g.stats.reservoirs = r->reservoirs();
          g.stats.meanM = r->mean_m();
          g.stats.meanNeighbours = r->mean_neighbours();
          slowest = std::max(slowest, r->seconds_primal() + r->seconds_derivative() + r->seconds_reservoir() + r->seconds_session() +
                                          r->seconds_stage1() + r->seconds_variance());
          out[s] = std::move(g);
        }
        return out;
      };
      while (!loop.done()) {
        const bool burnIn = loop.burningIn();
        std::optional<GradientResult> g;
        try {
          g = loop.next(evaluateOnWorkers);
        } catch (const InputError& err) {  // divergence: the loop kept the last good state
          throw JobFailed{std::string(err.what()) + "; the last good checkpoint (step " + std::to_string(loop.state().step) + ") is kept"};
        }
        if (burnIn) {
          const uint64_t c = loop.state().counter;
          if (c == 1 || c == uint64_t(p.burnIn))
            logEvent(id, "burn-in " + std::to_string(c) + "/" + std::to_string(p.burnIn) + " (render-only steps that fill the reservoirs)");
          continue;
        }
        auto u0 = Clock::now();
        const LoopState& ls = loop.state();
        theta = ls.theta;
        ++stepsThisRun;
        // Rates from the steps after this run's first (which includes building sessions and targets).
        if (stepsThisRun == 1) firstStepDone = Clock::now();
        double seconds = secondsBefore + std::chrono::duration<double>(Clock::now() - runStart).count();
        ck.set_step(ls.step);
        ck.set_counter(ls.counter);
        ck.mutable_theta()->Assign(ls.theta.begin(), ls.theta.end());
        ck.mutable_adam_m()->Assign(ls.optimizer.m.begin(), ls.optimizer.m.end());
        ck.mutable_adam_v()->Assign(ls.optimizer.v.begin(), ls.optimizer.v.end());
        ck.set_optimizer_step(ls.optimizer.step);
        ck.set_seconds(seconds);
        jobs.saveCheckpoint(id, ck);  // before the progress event: the log never runs ahead of it
        haveCheckpoint = true;
        double perStep = stepsThisRun == 1 ? wall : std::chrono::duration<double>(Clock::now() - firstStepDone).count() / double(stepsThisRun - 1);
        const GradientStats& st = g->stats;
        v1::StepProgress sp;
        sp.set_render_seconds(st.secondsPrimal);
        sp.set_derivative_seconds(st.secondsDerivative);
        sp.set_reservoir_seconds(st.secondsReservoirUpdate);
        sp.set_stage1_seconds(st.secondsStage1);
        if (p.gradient.variance.enabled) {
          sp.set_bias_term(st.biasTerm);
          sp.set_variance_term(st.varianceTerm);
          sp.set_cost(st.cost);
          sp.set_variance_seconds(st.secondsVariance);
        }
        sp.set_reservoirs(st.reservoirs);
        sp.set_mean_m(st.meanM);
        sp.set_mean_neighbours(st.meanNeighbours);
        sp.set_step(ls.step);
        sp.set_steps(uint64_t(p.steps));
        sp.set_loss(st.loss);
        sp.set_param_error(p.groundTruthKnown() ? parameterError(p, ls.theta) : -1.0);
        sp.set_seconds(seconds);
        sp.set_steps_per_second(1.0 / perStep);
        sp.set_eta_seconds(perStep * double(uint64_t(p.steps) - ls.step));
        sp.set_non_finite(st.nonFiniteSamples);
        sp.set_transport_seconds(std::max(0.0, wall - slowest));
        sp.set_update_seconds(std::chrono::duration<double>(Clock::now() - u0).count());
        csv.push_back(method + "," + std::to_string(ls.step) + "," + std::to_string(seconds) + "," + fmtDouble(sp.loss()) + "," +
                      fmtDouble(sp.param_error()));
        std::lock_guard<std::mutex> lk(mu);
        JobEntry& j = jobTable.at(id);
        j.step = ls.step;
        j.loss = sp.loss();
        j.paramError = sp.param_error();
        j.seconds = seconds;
        v1::ProgressEvent ev;
        *ev.mutable_step() = sp;
        publishLocked(j, std::move(ev));
        spdlog::info("[{} step {}] loss {:.6g} param_error {:.4g} ({:.2f} steps/s)", id, ls.step, sp.loss(), sp.param_error(),
                     sp.steps_per_second());
      }
      writeResults(run, p, theta, csv);
      std::lock_guard<std::mutex> lk(mu);
      endJobLocked(jobTable.at(id), v1::SUCCEEDED);
    } catch (const JobCancelled&) {
      std::lock_guard<std::mutex> lk(mu);
      JobEntry& j = jobTable.at(id);
      if (stopping && !j.cancelRequested) return;  // server shutting down: the job resumes on restart
      j.rec.set_reason("cancelled by request");
      endJobLocked(j, v1::CANCELLED);
    } catch (const JobFailed& f) {
      failJob(id, f.reason, p, haveCheckpoint ? &ck : nullptr);
    } catch (const InputError& e) {
      failJob(id, e.what(), p, haveCheckpoint ? &ck : nullptr);
    } catch (const std::exception& e) {
      failJob(id, std::string("internal error: ") + e.what(), p, haveCheckpoint ? &ck : nullptr);
    }
  }

  static std::string fmtDouble(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.9g", v);
    return b;
  }

  void failJob(const std::string& id, const std::string& reason, const Problem& p, const v1::Checkpoint* ck) {
    std::vector<std::string> files;
    // The last good parameters stay fetchable, next to the log.
    if (ck && p.params.size() == size_t(ck->theta_size())) {
      try {
        files = writeParameters(jobs.resultsDir(id), p.params, std::vector<float>(ck->theta().begin(), ck->theta().end()));
      } catch (const std::exception&) {
      }
    }
    std::lock_guard<std::mutex> lk(mu);
    JobEntry& j = jobTable.at(id);
    copyLogLocked(id, files);
    j.rec.clear_results();
    for (auto& f : files) j.rec.add_results(f);
    j.rec.set_reason(reason);
    endJobLocked(j, v1::FAILED);
  }

  void copyLogLocked(const std::string& id, std::vector<std::string>& files) {
    std::error_code ec;
    std::filesystem::copy_file(jobs.jobDir(id) / "progress.jsonl", jobs.resultsDir(id) / "progress.jsonl",
                               std::filesystem::copy_options::overwrite_existing, ec);
    if (!ec) files.push_back("progress.jsonl");
  }

  void writeResults(Run& run, Problem& p, const std::vector<float>& theta, const std::vector<std::string>& csv) {
    auto dir = jobs.resultsDir(run.id);
    std::filesystem::create_directories(dir);
    std::vector<std::string> files = writeParameters(dir, p.params, theta);
    {
      // The convergence CSV of the whole job, rebuilt from the log (it survives restarts).
      std::ofstream out(dir / "convergence.csv");
      out << kConvergenceCsvHeader << "\n";
      std::vector<v1::ProgressEvent> evs = jobs.loadEvents(run.id);
      std::map<uint64_t, std::string> rows;
      for (const auto& e : evs)
        if (e.has_step())
          rows[e.step().step()] = gradientMethodName(p.gradient.method) + std::string(",") + std::to_string(e.step().step()) + "," +
                                  std::to_string(e.step().seconds()) + "," + fmtDouble(e.step().loss()) + "," + fmtDouble(e.step().param_error());
      for (auto& [k, r] : rows) out << r << "\n";
      (void)csv;
      files.push_back("convergence.csv");
    }
    // Charts are the client's: `invr fetch` and `invr run` draw convergence.png from this CSV.
    // Final renders (and the targets beside them) from the workers.
    logEvent(run.id, "rendering final images");
    std::vector<std::optional<v1::Task>> tasks(p.shards.size());
    for (size_t s = 0; s < p.shards.size(); ++s) {
      v1::Task t = baseTask(run, s, theta);
      t.set_kind(v1::Task::FINAL_RENDER);
      t.set_final_spp(opt.finalSpp);
      for (int v : p.shards[s])
        if (v < opt.finalViews) t.add_views(v);
      if (t.views_size() > 0) tasks[s] = std::move(t);
    }
    auto results = dispatch(run, tasks);
    for (size_t s = 0; s < results.size(); ++s) {
      if (!results[s]) continue;
      const auto& r = *results[s];
      int nv = tasks[s]->views_size();
      for (int k = 0; k < r.renders_size() && k < 2 * nv; ++k) {
        const v1::FloatImage& fi = r.renders(k);
        Image im(fi.width(), fi.height(), fi.channels());
        if (size_t(fi.pixels_size()) != im.data().size()) continue;
        std::copy(fi.pixels().begin(), fi.pixels().end(), im.data().begin());
        std::string stem = (k < nv ? "final_view" : "target_view") + std::to_string(tasks[s]->views(k % nv));
        for (const char* ext : {".png", ".exr"}) {
          writeImage(dir / (stem + ext), im);
          files.push_back(stem + ext);
        }
      }
      // Variance-aware jobs: the per-pixel variance of one sample, as the job now samples.
      for (int k = 0; k < r.variances_size() && k < nv; ++k) {
        const v1::FloatImage& fi = r.variances(k);
        Image im(fi.width(), fi.height(), fi.channels());
        if (size_t(fi.pixels_size()) != im.data().size()) continue;
        std::copy(fi.pixels().begin(), fi.pixels().end(), im.data().begin());
        std::string name = "variance_view" + std::to_string(tasks[s]->views(k)) + ".exr";
        writeImage(dir / name, im);
        files.push_back(name);
      }
    }
    for (auto& f : writeSelectionResults(dir, p.params, *p.scene, theta)) files.push_back(f);
    std::lock_guard<std::mutex> lk(mu);
    JobEntry& j = jobTable.at(run.id);
    copyLogLocked(run.id, files);
    j.rec.clear_results();
    for (auto& f : files) j.rec.add_results(f);
  }

  void load() {
    std::lock_guard<std::mutex> lk(mu);
    for (auto& rec : jobs.loadAll()) {
      JobEntry j;
      j.rec = rec;
      j.events = jobs.loadEvents(rec.job_id());
      j.nextSeq = j.events.empty() ? 1 : j.events.back().sequence() + 1;
      for (const auto& e : j.events)
        if (e.has_step()) {
          j.step = e.step().step();
          j.steps = e.step().steps();
          j.loss = e.step().loss();
          j.paramError = e.step().param_error();
          j.seconds = e.step().seconds();
        }
      std::string id = rec.job_id();
      if (!rec.request_id().empty()) byRequestId[rec.request_id()] = id;
      bool unfinished = !finished(rec.state());
      auto& entry = jobTable[id] = std::move(j);
      if (unfinished) {
        entry.rec.set_state(v1::QUEUED);
        queue.push_back(id);
        logEventLocked(entry, "server restarted; queued again");
      }
    }
  }
};

Server::Server(ServerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

Server::~Server() { shutdown(); }

int Server::start() {
  // One server per store: a second one would split clients between two views of the same jobs.
  std::filesystem::create_directories(impl_->opt.storeDir);
  impl_->storeLock = ::open((impl_->opt.storeDir / "LOCK").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (impl_->storeLock < 0 || ::flock(impl_->storeLock, LOCK_EX | LOCK_NB) != 0)
    throw InputError("store '" + impl_->opt.storeDir.string() + "' is in use by another invr-server");
  impl_->load();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  int port = 0;
  // Exclusive bind: without this gRPC sets SO_REUSEPORT, and a second server on the same port
  // would start and take half of the connections.
  b.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  b.AddListeningPort(impl_->opt.address, grpc::InsecureServerCredentials(), &port);
  b.SetMaxReceiveMessageSize(wire::kMaxMessageBytes);
  b.SetMaxSendMessageSize(wire::kMaxMessageBytes);
  b.RegisterService(static_cast<v1::InvrService::CallbackService*>(impl_.get()));
  b.RegisterService(static_cast<v1::WorkerService::CallbackService*>(impl_.get()));
  impl_->grpcServer = b.BuildAndStart();
  if (!impl_->grpcServer || port == 0)
    throw std::runtime_error("cannot listen on " + impl_->opt.address + " (address in use, perhaps by another invr-server, or not a local address)");
  impl_->controlThread = std::thread([this] { impl_->controlLoop(); });
  impl_->runnerThread = std::thread([this] { impl_->runnerLoop(); });
  spdlog::info("invr-server listening on port {} (store {})", port, impl_->opt.storeDir.string());
  return port;
}

void Server::shutdown() {
  if (!impl_ || !impl_->grpcServer) return;
  {
    std::lock_guard<std::mutex> lk(impl_->mu);
    if (impl_->stopping) return;
    impl_->stopping = true;
    for (auto& [id, w] : impl_->workers)
      if (w.stream) w.stream->close();
    for (auto& [id, j] : impl_->jobTable)
      for (auto* w : j.watchers) w->close(grpc::Status(grpc::StatusCode::UNAVAILABLE, "server shutting down"));
  }
  impl_->cv.notify_all();
  impl_->controlCv.notify_all();
  if (impl_->runnerThread.joinable()) impl_->runnerThread.join();
  if (impl_->controlThread.joinable()) impl_->controlThread.join();
  impl_->grpcServer->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
}

void Server::wait() {
  if (impl_->grpcServer) impl_->grpcServer->Wait();
}

}  // namespace invr::server
