// A progress bar on a terminal (stderr), nothing otherwise.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace invr {

class ProgressBar {
 public:
  explicit ProgressBar(std::string label) : label_(std::move(label)), tty_(isatty(fileno(stderr)) != 0) {}
  // `detail` follows the bar (e.g. "loss 0.0123  eta 42 s"); the line is cleared of a longer
  // previous one.
  void update(double fraction, const std::string& detail = "") {
    if (!tty_) return;
    auto now = std::chrono::steady_clock::now();
    if (fraction < 1.0 && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    int filled = int(fraction * 30.0 + 0.5);
    double secs = std::chrono::duration<double>(now - start_).count();
    std::fprintf(stderr, "\r%s [%s%s] %3d%%  %.1fs%s%s\033[K", label_.c_str(), std::string(size_t(filled), '#').c_str(),
                 std::string(size_t(30 - filled), ' ').c_str(), int(fraction * 100.0 + 0.5), secs, detail.empty() ? "" : "  ",
                 detail.c_str());
    std::fflush(stderr);
  }
  void finish() {
    if (tty_) std::fprintf(stderr, "\n");
  }

 private:
  std::string label_;
  bool tty_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), last_{};
};

}  // namespace invr
