// The worker's connection to the server: the Connect stream, a reader thread that queues what the
// server sends (and raises the cancel flag when the job of the task in hand is released), and a
// heartbeat thread that also carries out a SIGTERM drain. Tasks run on the caller's thread, one at
// a time, through the handlers.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <functional>
#include <optional>
#include <string>

#include "invr/v1/service.pb.h"
#include "worker/worker.h"

namespace invr::worker {

class Connection {
 public:
  struct Handlers {
    std::function<std::optional<invr::v1::WorkerMessage>(const invr::v1::Task&)> task;  // nullopt: no answer
    std::function<void(const std::string& job)> release;                                // the job ended
  };
  // `cancel` is lowered when a task starts and raised to stop it; `shouldStop` says when to leave.
  Connection(const WorkerOptions& options, std::atomic<bool>& cancel, std::function<bool()> shouldStop)
      : opt_(options), cancel_(cancel), shouldStop_(std::move(shouldStop)) {}
  // One connection, until the server ends it or the worker leaves. True when the server welcomed
  // the worker (it got as far as a worker id).
  bool serve(const Handlers& handlers);
  // Set when the server refused the worker's credentials (UNAUTHENTICATED, PERMISSION_DENIED).
  const grpc::Status& refusal() const { return refusal_; }

 private:
  void noteRefusal(const grpc::Status& st);

  const WorkerOptions& opt_;
  std::atomic<bool>& cancel_;
  std::function<bool()> shouldStop_;
  grpc::Status refusal_ = grpc::Status::OK;
};

}  // namespace invr::worker
