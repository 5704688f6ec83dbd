// Wall-clock seconds since a start, on the steady clock: the one timer of the code base.
#pragma once

#include <chrono>

namespace invr {

class Stopwatch {
 public:
  using Clock = std::chrono::steady_clock;
  Stopwatch() : start_(Clock::now()) {}
  explicit Stopwatch(Clock::time_point start) : start_(start) {}
  double seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
  // The seconds so far, and starts again from now.
  double lap() {
    const Clock::time_point now = Clock::now();
    const double s = std::chrono::duration<double>(now - start_).count();
    start_ = now;
    return s;
  }
  void restart() { start_ = Clock::now(); }
  Clock::time_point started() const { return start_; }

 private:
  Clock::time_point start_;
};

}  // namespace invr
