// Benchmarks print a readable table, or with --json one JSON object with the named figures.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace invr {

class BenchReport {
 public:
  explicit BenchReport(std::string title) : title_(std::move(title)) {}
  void text(const std::string& key, const std::string& value) { rows_.push_back({key, "\"" + value + "\"", value}); }
  void number(const std::string& key, double value, const std::string& unit = "") {
    rows_.push_back({key, fmt(value), fmt(value) + (unit.empty() ? "" : " " + unit)});
  }
  // A pre-formatted JSON value (e.g. an object) with its table display.
  void raw(const std::string& key, const std::string& json, const std::string& display) { rows_.push_back({key, json, display}); }
  static std::string fmt(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
  }
  void print(bool json) const {
    if (json) {
      std::printf("{\"benchmark\": \"%s\"", title_.c_str());
      for (const auto& r : rows_) std::printf(", \"%s\": %s", r.key.c_str(), r.json.c_str());
      std::printf("}\n");
      return;
    }
    std::printf("%s\n", title_.c_str());
    size_t w = 0;
    for (const auto& r : rows_) w = std::max(w, r.key.size());
    for (const auto& r : rows_) std::printf("  %-*s  %s\n", int(w), r.key.c_str(), r.display.c_str());
  }

 private:
  struct Row { std::string key, json, display; };
  std::string title_;
  std::vector<Row> rows_;
};

}  // namespace invr
