// Task execution: a task from the server, evaluated on its shard's session (built first when the
// worker has none: scene, targets, engine, and a burn-in when it takes over mid-job), answered as a
// TaskResult. Errors become the result's error (input errors are not retried); a cancelled task
// has no answer.
#pragma once

#include <atomic>
#include <optional>
#include <string>

#include "invr/v1/service.pb.h"
#include "worker/asset_cache.h"
#include "worker/sessions.h"

namespace invr::worker {

class TaskRunner {
 public:
  // `cancel` is raised by the connection when the task's job ends or the worker must hand it back.
  TaskRunner(SessionCache& sessions, SpecCache& specs, AssetCache& assets, const std::atomic<bool>& cancel, std::string workerName)
      : sessions_(sessions), specs_(specs), assets_(assets), cancel_(cancel), name_(std::move(workerName)) {}
  // The answer to `task`; nullopt when it was cancelled (the server reassigns it).
  std::optional<invr::v1::WorkerMessage> execute(const invr::v1::Task& task);

 private:
  Session& session(const invr::v1::Task& t, const invr::v1::JobSpec& spec, invr::v1::TaskResult& res);

  SessionCache& sessions_;
  SpecCache& specs_;
  AssetCache& assets_;
  const std::atomic<bool>& cancel_;
  std::string name_;
};

}  // namespace invr::worker
