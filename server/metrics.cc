#include "server/metrics.h"

#include <httplib.h>

#include <sstream>
#include <stdexcept>

namespace invr::server {

namespace {

void gauge(std::ostringstream& o, const char* name, const char* help, double v) {
  o << "# HELP " << name << " " << help << "\n# TYPE " << name << " gauge\n" << name << " " << v << "\n";
}

}  // namespace

void StepMetrics::stepDone(double seconds) {
  std::lock_guard<std::mutex> lk(mu_);
  ++count_;
  sum_ += seconds;
  for (size_t i = 0; i < std::size(kBuckets); ++i)
    if (seconds <= kBuckets[i]) ++buckets_[i];
  recent_.push_back(std::chrono::steady_clock::now());
}

std::string StepMetrics::render(const MetricsSnapshot& s) const {
  std::ostringstream o;
  o.precision(10);
  gauge(o, "invr_queue_depth", "Jobs waiting to run.", double(s.queued));
  gauge(o, "invr_running_jobs", "Jobs running now.", double(s.running));
  o << "# HELP invr_jobs Jobs in the store that ended, by final state.\n# TYPE invr_jobs gauge\n";
  o << "invr_jobs{state=\"succeeded\"} " << s.succeeded << "\ninvr_jobs{state=\"failed\"} " << s.failed << "\ninvr_jobs{state=\"cancelled\"} "
    << s.cancelled << "\n";
  gauge(o, "invr_connected_workers", "Workers connected now.", double(s.workers));
  gauge(o, "invr_busy_workers", "Connected workers with a task in flight.", double(s.busyWorkers));
  gauge(o, "invr_worker_threads", "Render threads of the connected workers.", double(s.workerThreads));
  std::lock_guard<std::mutex> lk(mu_);
  auto now = std::chrono::steady_clock::now();
  while (!recent_.empty() && now - recent_.front() > std::chrono::seconds(60)) recent_.pop_front();
  const double window = std::min(60.0, std::max(1.0, std::chrono::duration<double>(now - started_).count()));
  gauge(o, "invr_steps_per_second", "Gradient steps applied per second over the last minute, all jobs.", double(recent_.size()) / window);
  o << "# HELP invr_steps_total Gradient steps applied since the server started.\n# TYPE invr_steps_total counter\ninvr_steps_total "
    << count_ << "\n";
  o << "# HELP invr_step_seconds Wall time of one gradient step of one job (dispatch, workers, update, checkpoint).\n"
       "# TYPE invr_step_seconds histogram\n";
  for (size_t i = 0; i < std::size(kBuckets); ++i) o << "invr_step_seconds_bucket{le=\"" << kBuckets[i] << "\"} " << buckets_[i] << "\n";
  o << "invr_step_seconds_bucket{le=\"+Inf\"} " << count_ << "\ninvr_step_seconds_sum " << sum_ << "\ninvr_step_seconds_count " << count_ << "\n";
  return o.str();
}

struct MetricsEndpoint::Impl {
  httplib::Server http;
  std::thread thread;
};

MetricsEndpoint::MetricsEndpoint(const std::string& address, std::function<std::string()> body) : impl_(std::make_unique<Impl>()) {
  auto colon = address.rfind(':');
  if (colon == std::string::npos) throw std::runtime_error("--metrics-address '" + address + "': expected host:port");
  std::string host = address.substr(0, colon);
  if (host.size() > 1 && host.front() == '[') host = host.substr(1, host.size() - 2);
  int port = 0;
  try {
    port = std::stoi(address.substr(colon + 1));
  } catch (const std::exception&) {
    throw std::runtime_error("--metrics-address '" + address + "': the port is not a number");
  }
  impl_->http.Get("/metrics", [body](const httplib::Request&, httplib::Response& res) {
    res.set_content(body(), "text/plain; version=0.0.4; charset=utf-8");
  });
  port_ = port == 0 ? impl_->http.bind_to_any_port(host) : (impl_->http.bind_to_port(host, port) ? port : -1);
  if (port_ <= 0) throw std::runtime_error("--metrics-address '" + address + "': cannot listen there");
  impl_->thread = std::thread([this] { impl_->http.listen_after_bind(); });
  // stop() does nothing until the listener runs: wait for it, so that a quick shutdown cannot hang.
  for (int i = 0; i < 5000 && !impl_->http.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

MetricsEndpoint::~MetricsEndpoint() {
  impl_->http.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace invr::server
