#include "server/scheduler.h"
#include "core/stopwatch.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>

namespace invr::server {

namespace v1 = invr::v1;

namespace {

double secondsSince(Clock::time_point t) { return Stopwatch(t).seconds(); }

std::string fmtSeconds(double s) {
  char b[32];
  std::snprintf(b, sizeof b, "%g s", s);
  return b;
}

}  // namespace

Scheduler::Scheduler(SchedulerOptions options) : opt_(options) {}

// ------------------------------------------------------------------ workers

Scheduler::Worker* Scheduler::byLinkLocked(WorkerLink* link) {
  for (auto& [id, w] : workers_)
    if (w.link == link) return &w;
  return nullptr;
}

void Scheduler::freeWorkerLocked(Worker& w, uint64_t task) {
  if (w.inFlight == task) {
    w.inFlight = 0;
    w.inFlightJob.clear();
  }
}

void Scheduler::onMessage(WorkerLink* link, v1::WorkerMessage& m) {
  std::lock_guard<std::mutex> lk(mu_);
  Worker* w = byLinkLocked(link);
  if (m.has_hello()) {
    if (w || stopping_) return;
    Worker e;
    e.id = nextWorker_++;
    // A name is for logs and `invr workers`: bounded, printable.
    std::string name = m.hello().name().substr(0, 128);
    for (char& c : name)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    e.name = name.empty() ? "worker-" + std::to_string(e.id) : name;
    e.capacity = std::clamp<uint32_t>(m.hello().capacity(), 1, 4096);
    e.link = link;
    e.lastSeen = Clock::now();
    spdlog::info("worker {} ({}, {} threads) connected", e.id, e.name, e.capacity);
    v1::ServerMessage welcome;
    welcome.set_welcome(std::to_string(e.id));
    link->send(std::move(welcome));
    workers_[e.id] = std::move(e);
    pumpLocked();
    cv_.notify_all();
    return;
  }
  if (!w) return;  // nothing before hello
  w->lastSeen = Clock::now();
  auto revive = [&] {
    w->suspect = false;
    // The expired task is abandoned: the worker is free again.
    if (w->expiredTasks.count(w->inFlight)) freeWorkerLocked(*w, w->inFlight);
    w->expiredTasks.clear();
    spdlog::info("worker {} ({}) is alive again after its lease expired", w->id, w->name);
  };
  if (m.has_leaving()) {
    w->leaving = true;
    spdlog::info("worker {} ({}) is leaving", w->id, w->name);
  } else if (m.has_heartbeat()) {
    if (w->suspect && !w->expiredTasks.count(m.heartbeat().busy_task())) revive();
  } else if (m.has_result()) {
    if (w->suspect) revive();  // it finished (or gave up) an expired task: alive, and free
    const uint64_t taskId = m.result().task_id();
    auto it = leases_.find(taskId);
    // Exactly once: only the current lease's worker can complete it, and only once.
    if (it == leases_.end() || it->second.worker != w->id || it->second.done) {
      spdlog::debug("worker {}: stale result for task {} ignored", w->id, taskId);
      freeWorkerLocked(*w, taskId);
      pumpLocked();
      cv_.notify_all();
      return;
    }
    Lease& l = it->second;
    freeWorkerLocked(*w, taskId);
    auto job = jobs_.find(l.job);
    if (job != jobs_.end()) {
      double took = secondsSince(l.sent);
      job->second.workerSeconds += took;
      job->second.virtualTime += took / job->second.info.priority;
    }
    ResultShape shape = job != jobs_.end() ? job->second.info.shape : ResultShape{};
    std::string bad = checkTaskResult(l.task, m.result(), shape);
    if (bad.empty()) {
      l.result.Swap(m.mutable_result());
    } else {  // the task fails (and is retried elsewhere); nothing of the result is used
      spdlog::warn("worker {} ({}): malformed result for task {}: {}", w->id, w->name, l.taskId, bad);
      l.result = v1::TaskResult();
      l.result.set_error("malformed result (" + bad + ")");
    }
    l.done = true;
      // Its evaluation complete, the job is about to have work again (see pumpLocked).
    if (job != jobs_.end() && !outstandingLocked(job->second)) job->second.idleSince = Clock::now();
  }
  pumpLocked();
  cv_.notify_all();
}

void Scheduler::onGone(WorkerLink* link) {
  std::lock_guard<std::mutex> lk(mu_);
  if (Worker* w = byLinkLocked(link)) {
    w->link = nullptr;
    w->inFlight = 0;
    w->inFlightJob.clear();
    spdlog::warn("worker {} ({}) disconnected", w->id, w->name);
  }
  cv_.notify_all();
}

size_t Scheduler::loadLocked(uint64_t worker) const {
  size_t n = 0;
  for (const auto& [id, j] : jobs_) n += size_t(std::count(j.assignment.begin(), j.assignment.end(), worker));
  return n;
}

std::vector<v1::WorkerStatus> Scheduler::workers() const {
  std::lock_guard<std::mutex> lk(mu_);
  std::vector<v1::WorkerStatus> out;
  for (const auto& [id, w] : workers_) {
    if (!w.alive()) continue;
    v1::WorkerStatus s;
    s.set_name(w.name);
    s.set_capacity(w.capacity);
    s.set_leaving(w.leaving);
    s.set_shards(uint32_t(loadLocked(id)));
    uint32_t jobs = 0;
    for (const auto& [jid, j] : jobs_)
      if (std::count(j.assignment.begin(), j.assignment.end(), id) > 0) {
        ++jobs;
        s.add_job_ids(jid);
      }
    s.set_jobs(jobs);
    s.set_busy(w.inFlight != 0);
    if (w.inFlight != 0) s.set_current_job(w.inFlightJob);
    s.set_seconds_since_heard(std::chrono::duration<double>(Clock::now() - w.lastSeen).count());
    out.push_back(std::move(s));
  }
  return out;
}

size_t Scheduler::connectedWorkers() const {
  std::lock_guard<std::mutex> lk(mu_);
  return size_t(std::count_if(workers_.begin(), workers_.end(), [](const auto& kv) { return kv.second.alive(); }));
}

Scheduler::Counts Scheduler::counts() const {
  std::lock_guard<std::mutex> lk(mu_);
  Counts c;
  for (const auto& [id, w] : workers_) {
    if (!w.alive()) continue;
    ++c.connected;
    c.busy += w.inFlight != 0;
    c.threads += w.capacity;
  }
  return c;
}

unsigned Scheduler::maxWorkerThreads() const {
  std::lock_guard<std::mutex> lk(mu_);
  unsigned n = 0;
  for (const auto& [id, w] : workers_)
    if (w.alive()) n = std::max(n, w.capacity);
  return n;
}

void Scheduler::checkWorkersLocked() {
  for (auto& [id, w] : workers_)
    if (w.alive() && secondsSince(w.lastSeen) > opt_.heartbeatTimeoutSeconds) {
      spdlog::warn("worker {} ({}) silent for {:.0f} s: presumed gone", id, w.name, opt_.heartbeatTimeoutSeconds);
      WorkerLink* link = w.link;
      w.link = nullptr;
      w.inFlight = 0;
      w.inFlightJob.clear();
      link->close();
    }
}

// ------------------------------------------------------------------ jobs

void Scheduler::addJob(ScheduledJob info) {
  std::lock_guard<std::mutex> lk(mu_);
  Job j;
  j.order = nextOrder_++;
  const size_t n = info.shards;
  j.assignment.assign(n, 0);
  j.avoid.assign(n, 0);
  j.attempts.assign(n, 0);
  j.ready.assign(n, nullptr);
  j.leaseOf.assign(n, 0);
  if (info.priority <= 0) info.priority = 1;
  // A newcomer starts level with the jobs already running, not with their whole past.
  bool first = true;
  for (const auto& [id, o] : jobs_) {
    j.virtualTime = first ? o.virtualTime : std::min(j.virtualTime, o.virtualTime);
    first = false;
  }
  j.info = std::move(info);
  std::string id = j.info.id;
  jobs_[id] = std::move(j);
}

void Scheduler::removeJob(const std::string& id) {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it != jobs_.end()) {
    for (uint64_t l : it->second.leaseOf) leases_.erase(l);
    jobs_.erase(it);
  }
  // Its sessions (and spec) go on every worker; a task of it still running there is stopped,
  // and the worker may take the next one (it queues behind the release).
  for (auto& [wid, w] : workers_) {
    w.specsSent.erase(id);
    if (w.inFlightJob == id) freeWorkerLocked(w, w.inFlight);
    if (w.link) {
      v1::ServerMessage m;
      m.set_release_job(id);
      w.link->send(std::move(m));
    }
  }
  pumpLocked();
  cv_.notify_all();
}

double Scheduler::workerSeconds(const std::string& id) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  return it == jobs_.end() ? 0 : it->second.workerSeconds;
}

uint32_t Scheduler::workersOf(const std::string& id) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return 0;
  std::set<uint64_t> ws(it->second.assignment.begin(), it->second.assignment.end());
  ws.erase(0);
  return uint32_t(ws.size());
}

void Scheduler::wake() { cv_.notify_all(); }

void Scheduler::stop() {
  std::lock_guard<std::mutex> lk(mu_);
  stopping_ = true;
  for (auto& [id, w] : workers_)
    if (w.link) w.link->close();
  cv_.notify_all();
}

// A live worker for the shard: its sticky one if still there, else the least loaded eligible one
// (shards of every running job count), preferring any worker but the one that last failed the
// shard, and within the job's worker cap.
uint64_t Scheduler::pickWorkerLocked(Job& job, size_t shard) {
  uint64_t w = job.assignment[shard];
  if (w && workers_.count(w) && workers_[w].alive() && !workers_[w].suspect) return w;
  if (w) {  // its worker vanished (or stalled) between steps
    job.info.log("shard " + std::to_string(shard) + ": worker " + workers_[w].name +
                 (workers_[w].alive() ? " unresponsive" : " lost") + "; reassigning");
    job.assignment[shard] = 0;
  }
  std::set<uint64_t> held;
  for (uint64_t a : job.assignment)
    if (a && workers_[a].eligible()) held.insert(a);
  const bool capped = job.info.maxWorkers > 0 && held.size() >= job.info.maxWorkers;
  uint64_t best = 0;
  std::tuple<bool, size_t, size_t> bestKey{};  // (is the avoided worker, load of all jobs, load of this job)
  for (auto& [id, e] : workers_) {
    if (!e.eligible() || (capped && !held.count(id))) continue;
    std::tuple<bool, size_t, size_t> key{id == job.avoid[shard], loadLocked(id),
                                         size_t(std::count(job.assignment.begin(), job.assignment.end(), id))};
    if (!best || key < bestKey) best = id, bestKey = key;
  }
  if (best) {
    job.assignment[shard] = best;
    if (w) job.info.log("shard " + std::to_string(shard) + " moved to worker " + workers_[best].name + " (rebuilding its state)");
  }
  return best;
}

void Scheduler::sendLocked(Job& job, size_t s, Worker& w) {
  v1::Task t = *job.ready[s];
  job.ready[s] = nullptr;
  t.set_task_id(nextTask_++);
  t.set_spec_sha256(job.info.specHash);
  Lease l;
  l.taskId = t.task_id();
  l.job = job.info.id;
  l.shard = s;
  l.worker = w.id;
  l.sent = Clock::now();
  l.deadline = l.sent + std::chrono::milliseconds(int64_t(opt_.leaseSeconds * 1000));
  // What the result is checked against (not θ: a texture's θ is megabytes).
  l.task.set_task_id(t.task_id());
  l.task.set_job_id(t.job_id());
  l.task.set_kind(t.kind());
  l.task.set_shard(t.shard());
  *l.task.mutable_views() = t.views();
  l.task.set_render_only(t.render_only());
  l.task.set_with_targets(t.with_targets());
  // The spec travels once per worker connection; later tasks name it by hash.
  if (auto [it, fresh] = w.specsSent.try_emplace(job.info.id, job.info.specHash); fresh || it->second != job.info.specHash) {
    it->second = job.info.specHash;
    *t.mutable_spec() = job.info.spec;
    l.sentSpec = true;
  }
  job.leaseOf[s] = l.taskId;
  w.inFlight = l.taskId;
  w.inFlightJob = job.info.id;
  leases_[l.taskId] = std::move(l);
  v1::ServerMessage m;
  *m.mutable_task() = std::move(t);
  w.link->send(std::move(m));
}

// Whether the job has a task waiting to be sent or one out on a worker.
bool Scheduler::outstandingLocked(const Job& job) const {
  for (size_t s = 0; s < job.ready.size(); ++s) {
    if (job.ready[s]) return true;
    if (job.leaseOf[s]) {
      auto it = leases_.find(job.leaseOf[s]);
      if (it != leases_.end() && !it->second.done) return true;
    }
  }
  return false;
}

// Gives each free worker the ready task of the job furthest behind in its fair share. A job that
// is further behind still but between evaluations keeps the worker waiting (briefly) for it.
void Scheduler::pumpLocked() {
  if (stopping_) return;
  const auto now = Clock::now();
  const auto anticipation = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kAnticipationSeconds));
  auto before = [](const Job& a, const Job& b) { return std::make_pair(a.virtualTime, a.order) < std::make_pair(b.virtualTime, b.order); };
  for (auto& [wid, w] : workers_) {
    if (!w.free()) continue;
    Job* best = nullptr;
    size_t bestShard = 0;
    for (auto& [jid, j] : jobs_) {
      if (best && !before(j, *best)) continue;
      for (size_t s = 0; s < j.ready.size(); ++s)
        if (j.ready[s] && j.assignment[s] == wid) {
          best = &j, bestShard = s;
          break;
        }
    }
    if (!best) continue;
    bool wait = false;
    for (auto& [jid, j] : jobs_) {
      if (&j == best || !before(j, *best) || j.idleSince + anticipation <= now || outstandingLocked(j)) continue;
      if (std::find(j.assignment.begin(), j.assignment.end(), wid) == j.assignment.end()) continue;
      wait = true;
          holdUntil_ = std::max(holdUntil_, j.idleSince + anticipation);
    }
    if (!wait) sendLocked(*best, bestShard, w);
  }
}

std::vector<std::optional<v1::TaskResult>> Scheduler::run(const std::string& id, const std::vector<std::optional<v1::Task>>& tasks) {
  std::unique_lock<std::mutex> lk(mu_);
  Job& job = jobs_.at(id);
  const size_t n = tasks.size();
  if (n != job.assignment.size()) throw std::logic_error("Scheduler::run: task count differs from the job's shards");
  std::vector<std::optional<v1::TaskResult>> results(n);
  std::fill(job.attempts.begin(), job.attempts.end(), 0);
  std::fill(job.leaseOf.begin(), job.leaseOf.end(), 0);
  for (size_t s = 0; s < n; ++s) job.ready[s] = tasks[s] ? &*tasks[s] : nullptr;
  // Back in the competition after a pause: credit for at most kRejoinSlackSeconds of it.
  {
    std::optional<double> least;
    for (const auto& [jid, o] : jobs_)
      if (jid != id && o.running) least = least ? std::min(*least, o.virtualTime) : o.virtualTime;
    if (least) job.virtualTime = std::max(job.virtualTime, *least - kRejoinSlackSeconds);
  }
  job.running = true;
  auto dropLease = [&](size_t s) {
    leases_.erase(job.leaseOf[s]);
    job.leaseOf[s] = 0;
  };
  // A worker that said it was leaving hands its task back: not a failed attempt.
  auto retry = [&](size_t s, const std::string& why, bool failed = true) {
    job.info.log("shard " + std::to_string(s) + ": " + why + "; reassigning");
    if (job.leaseOf[s]) job.avoid[s] = leases_[job.leaseOf[s]].worker;
    job.assignment[s] = 0;
    dropLease(s);
    job.ready[s] = &*tasks[s];
    if (failed && ++job.attempts[s] >= opt_.maxAttempts)
      throw JobFailed{"shard " + std::to_string(s) + " failed " + std::to_string(job.attempts[s]) + " times (last: " + why + ")"};
  };
  try {
    for (;;) {
      if (stopping_ || job.info.cancelled()) throw JobCancelled{};
      checkWorkersLocked();
      bool waiting = false;
      // Shards stick to the workers they start on, so a job that has more shards than connected
      // workers gives late workers (starting up, reconnecting after a server restart) a moment
      // before the first assignment.
      bool unassigned = std::all_of(job.assignment.begin(), job.assignment.end(), [](uint64_t w) { return w == 0; });
      size_t eligible = size_t(std::count_if(workers_.begin(), workers_.end(), [](const auto& kv) { return kv.second.eligible(); }));
      size_t wanted = job.info.maxWorkers ? std::min<size_t>(job.info.maxWorkers, n) : n;
      bool settle = unassigned && eligible > 0 && eligible < wanted && secondsSince(job.started) < opt_.assignGraceSeconds;
      for (size_t s = 0; s < n && !settle; ++s) {
        if (!job.ready[s]) continue;
        if (!pickWorkerLocked(job, s)) waiting = true;
      }
      pumpLocked();
      if (waiting && !job.announcedWaiting) {
        bool stalled = std::any_of(workers_.begin(), workers_.end(), [](const auto& kv) { return kv.second.alive() && kv.second.suspect; });
        job.info.log(stalled ? "waiting for an unresponsive worker to recover or another to connect" : "waiting for a worker to connect");
      }
      job.announcedWaiting = waiting;
      bool all = true;
      for (size_t s = 0; s < n; ++s) {
        if (!tasks[s] || results[s]) continue;
        if (!job.leaseOf[s]) {  // not sent yet
          all = false;
          continue;
        }
        Lease& l = leases_.at(job.leaseOf[s]);
        Worker& w = workers_.at(l.worker);
        if (l.done && l.result.error().empty() && !l.result.spec_unknown()) {
          results[s] = std::move(l.result);
          dropLease(s);
          continue;
        }
        all = false;
        if (l.done && l.result.spec_unknown() && !l.sentSpec) {
          // The worker lost the spec (it reconnected or dropped it): send it again, no attempt lost.
          w.specsSent.erase(id);
          dropLease(s);
          job.ready[s] = &*tasks[s];
          continue;
        }
        if (l.done) {
          if (l.result.input_error()) throw JobFailed{l.result.error()};
          retry(s, "worker " + w.name + " failed: " +
                       (l.result.spec_unknown() ? std::string("it did not take the job's spec") : l.result.error()));
        } else if (!w.alive()) {
          if (w.leaving)
            retry(s, "worker " + w.name + " left and handed its task back", false);
          else
            retry(s, "worker " + w.name + " lost");
        } else if (Clock::now() > l.deadline) {
          w.suspect = true;
          w.expiredTasks.insert(l.taskId);
          retry(s, "lease on worker " + w.name + " expired after " + fmtSeconds(opt_.leaseSeconds) +
                       " (no new lease for it until it shows it is alive)");
        }
      }
      if (all) break;
      auto wakeAt = Clock::now() + std::chrono::milliseconds(settle ? 20 : 100);
      if (holdUntil_ > Clock::now()) wakeAt = std::min(wakeAt, holdUntil_ + std::chrono::milliseconds(1));
      cv_.wait_until(lk, wakeAt);
    }
  } catch (...) {
    for (size_t s = 0; s < n; ++s) {
      if (job.leaseOf[s]) dropLease(s);
      job.ready[s] = nullptr;
    }
    job.running = false;
    job.idleSince = Clock::now();
    throw;
  }
  job.running = false;
  job.idleSince = Clock::now();
  return results;
}

}  // namespace invr::server
