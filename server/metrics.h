// The server's metrics in the Prometheus text format, served over HTTP (cpp-httplib) at
// /metrics for autoscalers and dashboards: queue depth, jobs by state, connected and busy
// workers, step latency (histogram), steps and steps per second over the last minute.
#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace invr::server {

// What the server knows at scrape time.
struct MetricsSnapshot {
  size_t queued = 0, running = 0, succeeded = 0, failed = 0, cancelled = 0;
  size_t workers = 0, busyWorkers = 0, workerThreads = 0;
};

class StepMetrics {
 public:
  static constexpr double kBuckets[] = {0.01, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 300};
  void stepDone(double seconds);
  // The whole exposition: the snapshot's gauges and the step histogram.
  std::string render(const MetricsSnapshot& s) const;

 private:
  mutable std::mutex mu_;
  uint64_t count_ = 0;
  double sum_ = 0;
  std::vector<uint64_t> buckets_ = std::vector<uint64_t>(std::size(kBuckets), 0);
  mutable std::deque<std::chrono::steady_clock::time_point> recent_;  // step ends in the last minute
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

// GET /metrics on its own thread. Throws when the address cannot be bound.
class MetricsEndpoint {
 public:
  MetricsEndpoint(const std::string& address, std::function<std::string()> body);
  ~MetricsEndpoint();
  int port() const { return port_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int port_ = 0;
};

}  // namespace invr::server
