// The server's book of jobs: every job's record and progress log (persisted in the JobStore),
// the queue of jobs waiting to run, request ids (idempotent submission) and progress watchers.
//
// Thread-safe. It never calls into the scheduler or the runners, so they may call it while
// holding their own locks.
#pragma once

#include <grpcpp/grpcpp.h>

#include <array>
#include <condition_variable>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "invr/v1/service.pb.h"
#include "server/job_store.h"

namespace invr::server {

// A client watching a job's progress (WatchJob).
class EventSink {
 public:
  virtual ~EventSink() = default;
  virtual void push(const invr::v1::ProgressEvent& e) = 0;  // the final event ends the stream
  virtual void close(grpc::Status status) = 0;
};

bool finishedState(invr::v1::JobState s);

class JobBook {
 public:
  JobBook(JobStore& store, int maxQueued);

  // Reads the store; unfinished jobs are queued again (in id order).
  void load();

  // ---- submission
  std::optional<std::string> jobOfRequest(const std::string& requestId) const;
  // OK, or RESOURCE_EXHAUSTED when the queue is full.
  grpc::Status roomInQueue() const;
  // Records and queues a validated job. A request id seen before returns its job (existing).
  // `submittedBy`: the client token's name (empty when tokens are off).
  grpc::Status add(const invr::v1::JobSpec& spec, const std::string& requestId, std::string* id, bool* existing,
                   const std::string& submittedBy = "");

  // ---- the queue (runner threads)
  // Blocks until a job is queued (marked RUNNING and returned) or stop() (nullopt).
  std::optional<std::string> take();
  size_t queued() const;
  size_t running() const;
  // Jobs by state: queued, running, succeeded, failed, cancelled.
  std::array<size_t, 5> countByState() const;

  // ---- a job's life
  invr::v1::JobSpec spec(const std::string& id) const;
  void log(const std::string& id, const std::string& message);
  // The job started (or resumed) running: its totals as the runner knows them.
  void started(const std::string& id, uint64_t step, uint64_t steps, const std::string& method);
  void stepDone(const std::string& id, const invr::v1::StepProgress& sp, double workerSeconds, uint32_t workers);
  bool cancelRequested(const std::string& id) const;
  // Adds files to a running job's results (snapshots), servable at once; the record is saved.
  void addResults(const std::string& id, const std::vector<std::string>& files);
  // Ends the job (saved, final event to watchers). `results` replaces its result list.
  void end(const std::string& id, invr::v1::JobState state, const std::string& reason, const std::vector<std::string>* results = nullptr);

  // ---- clients
  // Queued jobs end CANCELLED at once; running ones are flagged for their runner. Idempotent.
  grpc::Status cancel(const std::string& id, invr::v1::JobStatus* out, bool* wasQueued);
  grpc::Status status(const std::string& id, invr::v1::JobStatus* out) const;
  std::vector<invr::v1::JobStatus> list() const;
  grpc::Status resultPath(const std::string& id, const std::string& name, std::filesystem::path* path) const;
  // Sends the events from `fromSequence` on, then new ones as they come.
  grpc::Status watch(const std::string& id, uint64_t fromSequence, EventSink* sink);
  void unwatch(const std::string& id, EventSink* sink);
  // The job's events from `fromSequence` on, at most `max` of them (the dashboard polls these).
  grpc::Status events(const std::string& id, uint64_t fromSequence, size_t max, std::vector<invr::v1::ProgressEvent>* out) const;

  // Wakes take() (returns nullopt) and closes every watcher.
  void stop();

  static grpc::Status notFound(const std::string& id);

 private:
  struct Entry {
    invr::v1::JobRecord rec;
    std::vector<invr::v1::ProgressEvent> events;
    uint64_t nextSeq = 1;
    bool cancelRequested = false;
    uint64_t step = 0, steps = 0;
    double loss = std::numeric_limits<double>::quiet_NaN(), paramError = -1, seconds = 0, workerSeconds = 0;
    double stepsPerSecond = 0, etaSeconds = 0;
    uint32_t workers = 0;
    std::string method;
    std::set<EventSink*> watchers;
  };
  Entry& at(const std::string& id);
  const Entry& at(const std::string& id) const;
  invr::v1::JobStatus statusLocked(const Entry& j) const;
  void publishLocked(Entry& j, invr::v1::ProgressEvent ev);
  void logLocked(Entry& j, const std::string& message);
  void endLocked(Entry& j, invr::v1::JobState state);

  JobStore& store_;
  const int maxQueued_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, Entry> jobs_;
  std::map<std::string, std::string> byRequest_;
  std::deque<std::string> queue_;
  size_t running_ = 0;
  bool stopping_ = false;
};

}  // namespace invr::server
