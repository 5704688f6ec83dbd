#include "server/client_service.h"

#include <spdlog/spdlog.h>

#include "server/file_sender.h"
#include "server/job_resolver.h"
#include "server/raw_messages.h"
#include "server/write_queue.h"

namespace invr::server {

namespace v1 = invr::v1;

namespace {

// A client's WatchJob stream.
class Watcher final : public grpc::ServerWriteReactor<grpc::ByteBuffer>, public EventSink {
 public:
  Watcher(JobBook& book, std::string job) : book_(book), job_(std::move(job)), out_(this) {}
  void push(const v1::ProgressEvent& e) override { out_.push(toBytes(e), e.has_final()); }
  void close(grpc::Status st) override { out_.close(st); }
  void OnWriteDone(bool ok) override { out_.done(ok); }
  void OnCancel() override { out_.close(grpc::Status::CANCELLED); }
  void OnDone() override {
    book_.unwatch(job_, this);
    delete this;
  }

 private:
  JobBook& book_;
  std::string job_;
  WriteQueue<Watcher, grpc::ByteBuffer> out_;
};

class Uploader final : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  Uploader(const AssetStore& assets, uint64_t maxBytes, grpc::ByteBuffer* info) : info_(info), up_(assets, maxBytes), max_(maxBytes) {
    StartRead(&bytes_);
  }
  void OnReadDone(bool ok) override {
    if (ok) {
      // A chunk that does not parse ends the upload: nothing of it is kept.
      if (grpc::Status st = parseRequest(bytes_, chunk_); !st.ok()) return Finish(st);
      if (!up_.append(chunk_.data()))
        return Finish(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                   "upload: larger than the server's limit of " + std::to_string(max_) + " bytes"));
      return StartRead(&bytes_);
    }
    try {
      v1::AssetInfo info;
      info.set_size(up_.size());
      info.set_sha256(up_.commit());
      *info_ = toBytes(info);
      Finish(grpc::Status::OK);
    } catch (const std::exception& e) {
      Finish(grpc::Status(grpc::StatusCode::INTERNAL, e.what()));
    }
  }
  void OnDone() override { delete this; }

 private:
  grpc::ByteBuffer* info_;
  grpc::ByteBuffer bytes_;
  v1::AssetChunk chunk_;
  AssetStore::Upload up_;
  uint64_t max_;
};

grpc::ServerUnaryReactor* finish(grpc::CallbackServerContext* ctx, grpc::Status st) {
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(std::move(st));
  return reactor;
}

// An upload refused before its first chunk (authentication).
class RefusedUpload final : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  explicit RefusedUpload(grpc::Status st) { Finish(std::move(st)); }
  void OnDone() override { delete this; }
};

}  // namespace

ClientService::ClientService(JobBook& book, const Admission& admission, PreparedProblem& prepared, Scheduler& scheduler,
                             AssetStore& assets, uint64_t maxAssetBytes, ControlQueue& control, const Authenticator& auth)
    : book_(book),
      admission_(admission),
      prepared_(prepared),
      scheduler_(scheduler),
      assets_(assets),
      maxAssetBytes_(maxAssetBytes),
      control_(control),
      auth_(auth) {}

grpc::ServerReadReactor<grpc::ByteBuffer>* ClientService::UploadAsset(grpc::CallbackServerContext* ctx, grpc::ByteBuffer* info) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "UploadAsset"); !st.ok()) return new RefusedUpload(st);
  return new Uploader(assets_, maxAssetBytes_, info);
}

grpc::ServerUnaryReactor* ClientService::SubmitJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  std::string submittedBy;
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "SubmitJob", &submittedBy); !st.ok()) return finish(ctx, st);
  auto req = std::make_shared<v1::SubmitJobRequest>();
  if (grpc::Status st = parseRequest(*bytes, *req); !st.ok()) return finish(ctx, st);
  v1::SubmitJobResponse resp;
  if (req->request_id().size() > 256)  // it is stored with the job and kept in memory
    return finish(ctx, grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                    "request_id: " + std::to_string(req->request_id().size()) + " bytes long (limit 256)"));
  if (auto existing = book_.jobOfRequest(req->request_id())) {  // a retry: the same job, not a second one
    resp.set_job_id(*existing);
    resp.set_existing(true);
    return finishWith(ctx, grpc::Status::OK, resp, out);
  }
  if (grpc::Status room = book_.roomInQueue(); !room.ok()) return finish(ctx, room);
  auto* reactor = ctx->DefaultReactor();
  // Building the problem loads meshes and textures: not on a gRPC thread.
  control_.post([this, reactor, req, out, submittedBy] {
    grpc::Status st;
    v1::SubmitJobResponse resp;
    try {
      st = submit(*req, submittedBy, resp);
    } catch (const std::exception& e) {  // the store's disk, not the job: say so, keep serving
      st = grpc::Status(grpc::StatusCode::INTERNAL, std::string("job store: ") + e.what());
    }
    if (st.ok()) *out = toBytes(resp);
    reactor->Finish(st);
  });
  return reactor;
}

grpc::Status ClientService::submit(const v1::SubmitJobRequest& req, const std::string& submittedBy, v1::SubmitJobResponse& resp) {
  v1::JobSpec spec = req.spec();
  std::unique_ptr<Problem> validated;
  if (grpc::Status st = admission_.admit(spec, nullptr, &validated); !st.ok()) return st;
  std::string id;
  bool existing = false;
  if (grpc::Status st = book_.add(spec, req.request_id(), &id, &existing, submittedBy); !st.ok()) return st;
  resp.set_job_id(id);
  resp.set_existing(existing);
  if (!existing) prepared_.offer(id, std::move(validated));
  return grpc::Status::OK;
}

template <class Req, class Resp, class Work>
grpc::ServerUnaryReactor* ClientService::answerOffThread(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out,
                                                         const char* method, Work work) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, method); !st.ok()) return finish(ctx, st);
  auto req = std::make_shared<Req>();
  if (grpc::Status st = parseRequest(*bytes, *req); !st.ok()) return finish(ctx, st);
  auto* reactor = ctx->DefaultReactor();
  control_.post([reactor, req, out, work] {
    Resp resp;
    grpc::Status st;
    try {
      st = work(*req, &resp);
    } catch (const std::exception& e) {
      st = grpc::Status(grpc::StatusCode::INTERNAL, e.what());
    }
    if (st.ok()) *out = toBytes(resp);
    reactor->Finish(st);
  });
  return reactor;
}

grpc::ServerUnaryReactor* ClientService::PlanJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  return answerOffThread<v1::PlanJobRequest, v1::JobPlan>(ctx, bytes, out, "PlanJob", [this](v1::PlanJobRequest& req, v1::JobPlan* plan) {
    v1::JobSpec spec = req.spec();
    return admission_.admit(spec, plan);
  });
}

grpc::ServerUnaryReactor* ClientService::DescribeScene(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  return answerOffThread<v1::DescribeSceneRequest, v1::SceneDescription>(
      ctx, bytes, out, "DescribeScene", [this](v1::DescribeSceneRequest& req, v1::SceneDescription* desc) {
        v1::JobSpec spec = req.spec();
        return admission_.describe(spec, desc);
      });
}

grpc::ServerUnaryReactor* ClientService::ResolveJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  // Reads the uploaded scene files (an import parses XML): off the gRPC threads.
  return answerOffThread<v1::ResolveJobRequest, v1::ResolveJobResponse>(
      ctx, bytes, out, "ResolveJob", [this](v1::ResolveJobRequest& req, v1::ResolveJobResponse* resp) {
        return resolveJobRequest(req, assets_, *resp);
      });
}

grpc::ServerUnaryReactor* ClientService::GetJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "GetJob"); !st.ok()) return finish(ctx, st);
  v1::GetJobRequest req;
  if (grpc::Status st = parseRequest(*bytes, req); !st.ok()) return finish(ctx, st);
  v1::JobStatus resp;
  grpc::Status st = book_.status(req.job_id(), &resp);
  return finishWith(ctx, st, resp, out);
}

grpc::ServerUnaryReactor* ClientService::ListJobs(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "ListJobs"); !st.ok()) return finish(ctx, st);
  v1::ListJobsRequest req;
  if (grpc::Status st = parseRequest(*bytes, req); !st.ok()) return finish(ctx, st);
  v1::ListJobsResponse resp;
  for (auto& s : book_.list()) *resp.add_jobs() = std::move(s);
  return finishWith(ctx, grpc::Status::OK, resp, out);
}

grpc::ServerUnaryReactor* ClientService::CancelJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "CancelJob"); !st.ok()) return finish(ctx, st);
  v1::CancelJobRequest req;
  if (grpc::Status st = parseRequest(*bytes, req); !st.ok()) return finish(ctx, st);
  v1::JobStatus resp;
  bool wasQueued = false;
  grpc::Status st = book_.cancel(req.job_id(), &resp, &wasQueued);
  if (wasQueued) prepared_.drop(req.job_id());
  scheduler_.wake();  // a running job's runner sees the request now, not at its next poll
  return finishWith(ctx, st, resp, out);
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* ClientService::WatchJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes) {
  v1::WatchJobRequest req;
  grpc::Status parsed = parseRequest(*bytes, req);
  auto* w = new Watcher(book_, req.job_id());
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "WatchJob"); !st.ok()) {
    w->close(st);
    return w;
  }
  if (!parsed.ok()) {
    w->close(parsed);
    return w;
  }
  if (grpc::Status st = book_.watch(req.job_id(), req.from_sequence(), w); !st.ok()) w->close(st);
  return w;
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* ClientService::FetchResult(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes) {
  using Failed = FailedFileSenderOf<grpc::ByteBuffer>;
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "FetchResult"); !st.ok()) return new Failed(st);
  v1::FetchResultRequest req;
  if (grpc::Status st = parseRequest(*bytes, req); !st.ok()) return new Failed(st);
  std::filesystem::path path;
  if (grpc::Status st = book_.resultPath(req.job_id(), req.name(), &path); !st.ok()) return new Failed(st);
  return new FileSenderOf<grpc::ByteBuffer>(path);
}

grpc::ServerUnaryReactor* ClientService::ListWorkers(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Client, "ListWorkers"); !st.ok()) return finish(ctx, st);
  v1::ListWorkersRequest req;
  if (grpc::Status st = parseRequest(*bytes, req); !st.ok()) return finish(ctx, st);
  v1::ListWorkersResponse resp;
  for (auto& w : scheduler_.workers()) *resp.add_workers() = std::move(w);
  return finishWith(ctx, grpc::Status::OK, resp, out);
}

}  // namespace invr::server
