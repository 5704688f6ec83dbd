#include "server/worker_service.h"

#include "server/file_sender.h"
#include "server/write_queue.h"

namespace invr::server {

namespace v1 = invr::v1;

namespace {

// One worker connection: reads go to the scheduler, which writes back through WorkerLink.
class WorkerStream final : public grpc::ServerBidiReactor<v1::WorkerMessage, v1::ServerMessage>, public WorkerLink {
 public:
  explicit WorkerStream(Scheduler& s) : s_(s), out_(this) { StartRead(&in_); }
  void send(v1::ServerMessage m) override { out_.push(std::move(m)); }
  void close() override { out_.close(); }
  void OnReadDone(bool ok) override {
    if (!ok) {
      s_.onGone(this);
      out_.close();
      return;
    }
    s_.onMessage(this, in_);
    StartRead(&in_);
  }
  void OnWriteDone(bool ok) override { out_.done(ok); }
  void OnCancel() override { out_.close(); }
  void OnDone() override {
    s_.onGone(this);  // after this the scheduler no longer holds the link
    delete this;
  }

 private:
  Scheduler& s_;
  v1::WorkerMessage in_;
  WriteQueue<WorkerStream, v1::ServerMessage> out_;
};

// A connection refused before its first message (authentication).
class RefusedStream final : public grpc::ServerBidiReactor<v1::WorkerMessage, v1::ServerMessage> {
 public:
  explicit RefusedStream(grpc::Status st) { Finish(std::move(st)); }
  void OnDone() override { delete this; }
};

}  // namespace

grpc::ServerBidiReactor<v1::WorkerMessage, v1::ServerMessage>* WorkerService::Connect(grpc::CallbackServerContext* ctx) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Worker, "Connect"); !st.ok()) return new RefusedStream(st);
  return new WorkerStream(scheduler_);
}

grpc::ServerWriteReactor<v1::AssetChunk>* WorkerService::FetchAsset(grpc::CallbackServerContext* ctx, const v1::FetchAssetRequest* req) {
  if (grpc::Status st = auth_.check(ctx, CallerRole::Worker, "FetchAsset"); !st.ok()) return new FailedFileSender(st);
  if (!assets_.has(req->sha256()))
    return new FailedFileSender(grpc::Status(grpc::StatusCode::NOT_FOUND, "no asset " + req->sha256().substr(0, 64)));
  return new FileSender(assets_.path(req->sha256()));
}

}  // namespace invr::server
