#include "server/job_book.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

namespace invr::server {

namespace v1 = invr::v1;

namespace {

int64_t unixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

const char* stateName(v1::JobState s) { return v1::JobState_Name(s).c_str(); }

}  // namespace

bool finishedState(v1::JobState s) { return s == v1::SUCCEEDED || s == v1::FAILED || s == v1::CANCELLED; }

JobBook::JobBook(JobStore& store, int maxQueued) : store_(store), maxQueued_(maxQueued) {}

grpc::Status JobBook::notFound(const std::string& id) {
  // The id is the caller's: echo a bounded part of it.
  return grpc::Status(grpc::StatusCode::NOT_FOUND, "no job '" + id.substr(0, 64) + (id.size() > 64 ? "...'" : "'"));
}

JobBook::Entry& JobBook::at(const std::string& id) { return jobs_.at(id); }
const JobBook::Entry& JobBook::at(const std::string& id) const { return jobs_.at(id); }

void JobBook::load() {
  std::lock_guard<std::mutex> lk(mu_);
  for (auto& rec : store_.loadAll()) {
    Entry j;
    j.rec = rec;
    j.events = store_.loadEvents(rec.job_id());
    j.nextSeq = j.events.empty() ? 1 : j.events.back().sequence() + 1;
    // The method, as the runner names it when the job starts: a job that ended before this
    // restart never starts again, and keeps it.
    const v1::GradientMethod m = rec.spec().optimization().method();
    j.method = m == v1::METHOD_PT ? "pt" : m == v1::METHOD_RIS ? "ris" : "restir";
    for (const auto& e : j.events)
      if (e.has_step()) {
        j.step = e.step().step();
        j.steps = e.step().steps();
        j.loss = e.step().loss();
        j.paramError = e.step().param_error();
        j.seconds = e.step().seconds();
      }
    std::string id = rec.job_id();
    if (!rec.request_id().empty()) byRequest_[rec.request_id()] = id;
    bool unfinished = !finishedState(rec.state());
    auto& entry = jobs_[id] = std::move(j);
    if (unfinished) {
      entry.rec.set_state(v1::QUEUED);
      queue_.push_back(id);
      logLocked(entry, "server restarted; queued again");
    }
  }
}

std::optional<std::string> JobBook::jobOfRequest(const std::string& requestId) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = byRequest_.find(requestId);
  if (requestId.empty() || it == byRequest_.end()) return std::nullopt;
  return it->second;
}

grpc::Status JobBook::roomInQueue() const {
  std::lock_guard<std::mutex> lk(mu_);
  if (int(queue_.size()) >= maxQueued_)
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "queue full: " + std::to_string(queue_.size()) + " jobs waiting (limit " +
                                                                  std::to_string(maxQueued_) + "); retry later");
  return grpc::Status::OK;
}

grpc::Status JobBook::add(const v1::JobSpec& spec, const std::string& requestId, std::string* id, bool* existing,
                          const std::string& submittedBy) {
  std::lock_guard<std::mutex> lk(mu_);
  *existing = false;
  if (!requestId.empty()) {  // a concurrent retry may have won the race
    auto it = byRequest_.find(requestId);
    if (it != byRequest_.end()) {
      *id = it->second;
      *existing = true;
      return grpc::Status::OK;
    }
  }
  if (int(queue_.size()) >= maxQueued_)
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "queue full (limit " + std::to_string(maxQueued_) + "); retry later");
  Entry j;
  j.rec.set_job_id(store_.newJobId());
  j.rec.set_request_id(requestId);
  *j.rec.mutable_spec() = spec;
  j.rec.set_state(v1::QUEUED);
  j.rec.set_submitted_unix(unixMs() / 1000);
  j.rec.set_submitted_by(submittedBy);
  try {
    store_.saveRecord(j.rec);
  } catch (const std::exception& e) {
    return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
  }
  *id = j.rec.job_id();
  if (!requestId.empty()) byRequest_[requestId] = *id;
  auto& entry = jobs_[*id] = std::move(j);
  queue_.push_back(*id);
  logLocked(entry, "queued (" + std::to_string(queue_.size()) + " in queue)");
  spdlog::info("[{}] submitted: {}", *id, spec.name());
  cv_.notify_all();
  return grpc::Status::OK;
}

std::optional<std::string> JobBook::take() {
  std::unique_lock<std::mutex> lk(mu_);
  cv_.wait(lk, [&] { return stopping_ || !queue_.empty(); });
  if (stopping_) return std::nullopt;
  std::string id = queue_.front();
  queue_.pop_front();
  Entry& j = at(id);
  j.rec.set_state(v1::RUNNING);
  ++running_;
  try {
    store_.saveRecord(j.rec);
  } catch (const std::exception& e) {  // the runner fails it when it cannot write its checkpoint either
    spdlog::error("[{}] cannot save its record: {}", id, e.what());
  }
  return id;
}

size_t JobBook::queued() const {
  std::lock_guard<std::mutex> lk(mu_);
  return queue_.size();
}

size_t JobBook::running() const {
  std::lock_guard<std::mutex> lk(mu_);
  return running_;
}

std::array<size_t, 5> JobBook::countByState() const {
  std::lock_guard<std::mutex> lk(mu_);
  std::array<size_t, 5> n{};
  for (const auto& [id, j] : jobs_) {
    switch (j.rec.state()) {
      case v1::QUEUED: ++n[0]; break;
      case v1::RUNNING: ++n[1]; break;
      case v1::SUCCEEDED: ++n[2]; break;
      case v1::FAILED: ++n[3]; break;
      case v1::CANCELLED: ++n[4]; break;
      default: break;
    }
  }
  return n;
}

v1::JobSpec JobBook::spec(const std::string& id) const {
  std::lock_guard<std::mutex> lk(mu_);
  return at(id).rec.spec();
}

void JobBook::publishLocked(Entry& j, v1::ProgressEvent ev) {
  ev.set_sequence(j.nextSeq++);
  ev.set_unix_ms(unixMs());
  store_.appendEvent(j.rec.job_id(), ev);
  for (EventSink* w : j.watchers) w->push(ev);
  j.events.push_back(std::move(ev));
}

void JobBook::logLocked(Entry& j, const std::string& message) {
  v1::ProgressEvent ev;
  ev.set_message(message);
  spdlog::info("[{} step {}] {}", j.rec.job_id(), j.step, message);
  publishLocked(j, std::move(ev));
}

void JobBook::log(const std::string& id, const std::string& message) {
  std::lock_guard<std::mutex> lk(mu_);
  logLocked(at(id), message);
}

void JobBook::started(const std::string& id, uint64_t step, uint64_t steps, const std::string& method) {
  std::lock_guard<std::mutex> lk(mu_);
  Entry& j = at(id);
  j.step = step;
  j.steps = steps;
  j.method = method;
}

void JobBook::stepDone(const std::string& id, const v1::StepProgress& sp, double workerSeconds, uint32_t workers) {
  std::lock_guard<std::mutex> lk(mu_);
  Entry& j = at(id);
  j.step = sp.step();
  j.loss = sp.loss();
  j.paramError = sp.param_error();
  j.seconds = sp.seconds();
  j.workerSeconds = workerSeconds;
  j.workers = workers;
  j.stepsPerSecond = sp.steps_per_second();
  j.etaSeconds = sp.eta_seconds();
  v1::ProgressEvent ev;
  *ev.mutable_step() = sp;
  publishLocked(j, std::move(ev));
}

void JobBook::addResults(const std::string& id, const std::vector<std::string>& files) {
  std::lock_guard<std::mutex> lk(mu_);
  Entry& j = at(id);
  const auto& have = j.rec.results();
  for (const auto& f : files)
    if (std::find(have.begin(), have.end(), f) == have.end()) j.rec.add_results(f);
  try {
    store_.saveRecord(j.rec);
  } catch (const std::exception& e) {
    spdlog::error("[{}] cannot save its record: {}", j.rec.job_id(), e.what());
  }
}

bool JobBook::cancelRequested(const std::string& id) const {
  std::lock_guard<std::mutex> lk(mu_);
  return at(id).cancelRequested;
}

void JobBook::endLocked(Entry& j, v1::JobState state) {
  if (j.rec.state() == v1::RUNNING && running_ > 0) --running_;
  j.rec.set_state(state);
  j.workers = 0;
  try {
    store_.saveRecord(j.rec);
  } catch (const std::exception& e) {
    spdlog::error("[{}] cannot save its record: {}", j.rec.job_id(), e.what());
  }
  spdlog::info("[{} step {}] {}{}{}", j.rec.job_id(), j.step, stateName(state), j.rec.reason().empty() ? "" : ": ", j.rec.reason());
  v1::ProgressEvent ev;
  *ev.mutable_final() = statusLocked(j);
  publishLocked(j, std::move(ev));  // every watcher gets the final event, which ends its stream
}

void JobBook::end(const std::string& id, v1::JobState state, const std::string& reason, const std::vector<std::string>* results) {
  std::lock_guard<std::mutex> lk(mu_);
  Entry& j = at(id);
  if (!reason.empty()) j.rec.set_reason(reason);
  if (results) {
    j.rec.clear_results();
    for (const auto& f : *results) j.rec.add_results(f);
  }
  endLocked(j, state);
}

grpc::Status JobBook::cancel(const std::string& id, v1::JobStatus* out, bool* wasQueued) {
  std::lock_guard<std::mutex> lk(mu_);
  *wasQueued = false;
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return notFound(id);
  Entry& j = it->second;
  if (j.rec.state() == v1::QUEUED) {
    // Not started: nothing runs, so it ends here (the store write is one small file).
    queue_.erase(std::remove(queue_.begin(), queue_.end(), id), queue_.end());
    j.rec.set_reason("cancelled before it started");
    endLocked(j, v1::CANCELLED);
    *wasQueued = true;
  } else if (j.rec.state() == v1::RUNNING && !j.cancelRequested) {
    j.cancelRequested = true;  // the runner stops the job and its in-flight tasks
    logLocked(j, "cancel requested");
  }
  *out = statusLocked(j);  // idempotent: cancelling a finished job reports its state
  return grpc::Status::OK;
}

v1::JobStatus JobBook::statusLocked(const Entry& j) const {
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
  s.set_priority(std::max<uint32_t>(1, j.rec.spec().scheduling().priority()));
  s.set_worker_seconds(j.workerSeconds);
  s.set_workers(j.workers);
  if (j.rec.state() == v1::RUNNING) {
    s.set_steps_per_second(j.stepsPerSecond);
    s.set_eta_seconds(j.etaSeconds);
  }
  s.set_submitted_by(j.rec.submitted_by());
  return s;
}

grpc::Status JobBook::events(const std::string& id, uint64_t fromSequence, size_t max, std::vector<v1::ProgressEvent>* out) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return notFound(id);
  out->clear();
  const auto& ev = it->second.events;  // in sequence order
  auto from = std::lower_bound(ev.begin(), ev.end(), fromSequence,
                               [](const v1::ProgressEvent& e, uint64_t s) { return e.sequence() < s; });
  for (; from != ev.end() && out->size() < max; ++from) out->push_back(*from);
  return grpc::Status::OK;
}

grpc::Status JobBook::status(const std::string& id, v1::JobStatus* out) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return notFound(id);
  *out = statusLocked(it->second);
  return grpc::Status::OK;
}

std::vector<v1::JobStatus> JobBook::list() const {
  std::lock_guard<std::mutex> lk(mu_);
  std::vector<v1::JobStatus> out;
  for (const auto& [id, j] : jobs_) out.push_back(statusLocked(j));
  return out;
}

grpc::Status JobBook::resultPath(const std::string& id, const std::string& name, std::filesystem::path* path) const {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return notFound(id);
  const auto& res = it->second.rec.results();
  if (std::find(res.begin(), res.end(), name) == res.end())
    return grpc::Status(grpc::StatusCode::NOT_FOUND, "job " + id + " has no result '" + name.substr(0, 256) + "'");
  // The log is served live from the store: the copy among the results was made before the job's
  // final event, which the live one ends with.
  *path = name == "progress.jsonl" && std::filesystem::exists(store_.jobDir(id) / name) ? store_.jobDir(id) / name : store_.resultsDir(id) / name;
  return grpc::Status::OK;
}

grpc::Status JobBook::watch(const std::string& id, uint64_t fromSequence, EventSink* sink) {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return notFound(id);
  Entry& j = it->second;
  j.watchers.insert(sink);
  bool sentFinal = false;
  for (const auto& e : j.events)
    if (e.sequence() >= fromSequence) {
      sink->push(e);
      sentFinal = sentFinal || e.has_final();
    }
  if (finishedState(j.rec.state()) && !sentFinal) sink->close(grpc::Status::OK);  // resumed past the end
  return grpc::Status::OK;
}

void JobBook::unwatch(const std::string& id, EventSink* sink) {
  std::lock_guard<std::mutex> lk(mu_);
  auto it = jobs_.find(id);
  if (it != jobs_.end()) it->second.watchers.erase(sink);
}

void JobBook::stop() {
  std::lock_guard<std::mutex> lk(mu_);
  stopping_ = true;
  for (auto& [id, j] : jobs_)
    for (auto* w : j.watchers) w->close(grpc::Status(grpc::StatusCode::UNAVAILABLE, "server shutting down"));
  cv_.notify_all();
}

}  // namespace invr::server
