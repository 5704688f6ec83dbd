// The worker's per-job state, kept between tasks: what makes reservoirs persist. A session is one
// shard of one job (its scene and BVH, targets, gradient engine and ReSTIR chains); the specs are
// the jobs the server has sent on this connection, by the hash later tasks name them by.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/diff/gradient_engine.h"
#include "core/job/problem.h"
#include "invr/v1/service.pb.h"

namespace invr::worker {

struct Session {
  std::unique_ptr<Problem> problem;
  std::vector<Image> targets;  // the shard's views; others empty
  std::unique_ptr<GradientEngine> engine;
  EngineSession state;
  uint64_t lastUse = 0;
};

class SessionCache {
 public:
  // Least recently used sessions are evicted while there are maxSessions or more, or while the
  // process holds more than memoryLimitMb (an evicted shard is rebuilt, with a burn-in).
  SessionCache(size_t maxSessions, double memoryLimitMb, std::string workerName)
      : maxSessions_(maxSessions), memoryLimitMb_(memoryLimitMb), name_(std::move(workerName)) {}
  // The session of (job, shard), marked used; null when there is none.
  Session* find(const std::string& job, uint32_t shard);
  // Keeps a new session, evicting others first as needed.
  Session& insert(const std::string& job, uint32_t shard, Session session);
  void erase(const std::string& job, uint32_t shard) { sessions_.erase({job, shard}); }
  void release(const std::string& job);  // every shard of a job that ended
  void clear() { sessions_.clear(); }

 private:
  size_t maxSessions_;
  double memoryLimitMb_;
  std::string name_;
  std::map<std::pair<std::string, uint32_t>, Session> sessions_;
  uint64_t clock_ = 0;
};

// Job specs by hash: a job's spec comes whole with its first task on a connection, by hash after.
class SpecCache {
 public:
  // The task's spec (keeping it when the task carries it); null when the task names one this
  // worker does not hold (the server then sends it again).
  const invr::v1::JobSpec* specFor(const invr::v1::Task& task);
  void release(const std::string& job);
  void clear() {
    specs_.clear();
    specOfJob_.clear();
  }

 private:
  std::map<std::string, invr::v1::JobSpec> specs_;  // by spec hash
  std::map<std::string, std::string> specOfJob_;    // job id -> spec hash
};

// Resident memory of this process, in MiB (from /proc).
double residentMb();

}  // namespace invr::worker
