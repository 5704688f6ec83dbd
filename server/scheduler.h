// The scheduler: which worker evaluates which shard of which running job, and when.
//
// - Workers dial in (WorkerService) and are reached through a WorkerLink. Each has at most one
//   task in flight: the worker renders one task at a time with all its threads, so holding the
//   rest here lets the scheduler choose between jobs when the worker becomes free.
// - Shards are sticky: a shard stays on the worker it started on (its session holds the scene,
//   targets and ReSTIR reservoirs), unless that worker is lost, stalls or fails it.
// - Weighted fair share: a free worker takes the ready task of the job with the least worker time
//   per unit of priority (virtual time), so jobs that share workers get time in proportion to
//   their priorities while all have work. A job between two evaluations (its optimiser step) is
//   about to have work again: a free worker waits briefly (kAnticipation) for it rather than go to
//   a job that is ahead of it.
// - Leases: a task unanswered after the lease is reassigned and its worker is suspect (no new
//   lease) until it shows it is alive; a silent worker's stream is closed.
//
// Thread-safe. Job runner threads block in run(); the worker service calls onMessage/onGone.
// Lock order: the scheduler may call a job's `log`/`cancelled` callbacks under its lock, so those
// must not call back into the scheduler.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "invr/v1/service.pb.h"
#include "server/task_check.h"

namespace invr::server {

using Clock = std::chrono::steady_clock;

// How the scheduler reaches one worker connection.
class WorkerLink {
 public:
  virtual ~WorkerLink() = default;
  virtual void send(invr::v1::ServerMessage m) = 0;
  virtual void close() = 0;  // end the connection (a worker presumed gone)
};

// Thrown out of Scheduler::run.
struct JobCancelled {};
struct JobFailed {
  std::string reason;
};

// How long a free worker is held for a job that is behind in its share and between evaluations.
inline constexpr double kAnticipationSeconds = 0.05;
// A job that had no work for a while is not owed that time: it rejoins at most this many seconds
// (of worker time per unit of priority) behind the others.
inline constexpr double kRejoinSlackSeconds = 0.5;

struct SchedulerOptions {
  double leaseSeconds = 600;            // a task unanswered this long is reassigned
  double heartbeatTimeoutSeconds = 10;  // a silent worker is presumed gone
  int maxAttempts = 3;                  // per shard and evaluation, before the job fails
  double assignGraceSeconds = 3;        // at a job's start, wait this long for one worker per shard
};

// What the scheduler needs of a running job.
struct ScheduledJob {
  std::string id;
  invr::v1::JobSpec spec;  // sent once per worker connection; later tasks name it by hash
  std::string specHash;
  ResultShape shape;
  size_t shards = 0;
  double priority = 1;         // fair-share weight
  uint32_t maxWorkers = 0;     // distinct workers holding its shards; 0: no cap
  std::function<void(const std::string&)> log;  // a line in the job's progress log
  std::function<bool()> cancelled;              // polled while its tasks are out
};

class Scheduler {
 public:
  explicit Scheduler(SchedulerOptions options);

  // ---- workers (worker service)
  // A result is moved out of `m` (it may hold a θ-sized gradient).
  void onMessage(WorkerLink* link, invr::v1::WorkerMessage& m);
  void onGone(WorkerLink* link);
  std::vector<invr::v1::WorkerStatus> workers() const;
  size_t connectedWorkers() const;
  unsigned maxWorkerThreads() const;  // of the largest connected worker; 0 with none
  struct Counts {
    size_t connected = 0, busy = 0, threads = 0;
  };
  Counts counts() const;

  // ---- jobs (job runners)
  void addJob(ScheduledJob job);
  // Forgets the job and tells every worker to drop its sessions.
  void removeJob(const std::string& id);
  // Evaluates each present task on a worker and waits for all of them; results in shard order.
  // Throws JobCancelled (the job's `cancelled()` or stop()) or JobFailed (a shard failed
  // maxAttempts times, or a worker reported an input error).
  std::vector<std::optional<invr::v1::TaskResult>> run(const std::string& id, const std::vector<std::optional<invr::v1::Task>>& tasks);
  double workerSeconds(const std::string& id) const;
  uint32_t workersOf(const std::string& id) const;  // distinct workers holding its shards
  void wake();  // re-check cancellation now
  // Ends every worker connection; run() throws JobCancelled from now on.
  void stop();

 private:
  struct Worker {
    uint64_t id = 0;
    std::string name;
    uint32_t capacity = 1;
    WorkerLink* link = nullptr;  // null once the connection ended
    bool leaving = false;
    Clock::time_point lastSeen;
    // A worker whose lease expired gets no new lease until it proves alive: a heartbeat that is
    // idle or busy with a task whose lease did not expire, or any result.
    bool suspect = false;
    std::set<uint64_t> expiredTasks;
    std::map<std::string, std::string> specsSent;  // job id -> hash of the spec this connection holds
    uint64_t inFlight = 0;                         // task id sent and not answered
    std::string inFlightJob;
    bool alive() const { return link != nullptr; }
    bool eligible() const { return alive() && !leaving && !suspect; }
    bool free() const { return eligible() && inFlight == 0; }
  };
  struct Lease {
    uint64_t taskId = 0;
    std::string job;
    size_t shard = 0;
    uint64_t worker = 0;
    Clock::time_point sent, deadline;
    bool done = false;
    bool sentSpec = false;  // the task carried the whole spec
    invr::v1::Task task;    // what was asked (without spec and theta): results are checked against it
    invr::v1::TaskResult result;
  };
  struct Job {
    ScheduledJob info;
    uint64_t order = 0;                // arrival, to break ties
    std::vector<uint64_t> assignment;  // shard -> worker (0: none); sticky
    std::vector<uint64_t> avoid;       // shard -> worker that last failed it
    std::vector<int> attempts;         // failed attempts in the current evaluation
    std::vector<const invr::v1::Task*> ready;  // shard -> task waiting for its worker to be free
    std::vector<uint64_t> leaseOf;     // shard -> lease of the current evaluation (0: none)
    double virtualTime = 0;            // worker seconds / priority
    double workerSeconds = 0;
    bool running = false;              // inside run()
    Clock::time_point idleSince;       // when its last evaluation completed
    bool announcedWaiting = false;
    Clock::time_point started = Clock::now();
  };

  uint64_t pickWorkerLocked(Job& job, size_t shard);
  void pumpLocked();
  void sendLocked(Job& job, size_t shard, Worker& w);
  void checkWorkersLocked();
  void freeWorkerLocked(Worker& w, uint64_t task);
  size_t loadLocked(uint64_t worker) const;
  bool outstandingLocked(const Job& job) const;
  Worker* byLinkLocked(WorkerLink* link);

  SchedulerOptions opt_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<uint64_t, Worker> workers_;
  std::map<std::string, Job> jobs_;
  std::map<uint64_t, Lease> leases_;
  uint64_t nextWorker_ = 1, nextTask_ = 1, nextOrder_ = 1;
  Clock::time_point holdUntil_;  // a free worker is held for a job about to be ready until then
  bool stopping_ = false;
};

}  // namespace invr::server
