// A thread that runs posted work in order: what a gRPC callback must not do itself (building a
// job's problem reads meshes and textures).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace invr::server {

class ControlQueue {
 public:
  ControlQueue() : thread_([this] { loop(); }) {}
  ~ControlQueue() { stop(); }
  ControlQueue(const ControlQueue&) = delete;
  ControlQueue& operator=(const ControlQueue&) = delete;

  void post(std::function<void()> fn) {
    {
      std::lock_guard<std::mutex> lk(mu_);
      work_.push_back(std::move(fn));
    }
    cv_.notify_one();
  }
  // Runs what was posted, then joins.
  void stop() {
    {
      std::lock_guard<std::mutex> lk(mu_);
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void loop() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock<std::mutex> lk(mu_);
        cv_.wait(lk, [&] { return stopping_ || !work_.empty(); });
        if (work_.empty()) return;
        fn = std::move(work_.front());
        work_.pop_front();
      }
      fn();
    }
  }
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> work_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace invr::server
