// Benchmarks print a readable table, or with --json one JSON object with the named figures.
#pragma once

#include <algorithm>
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
  std::string json() const {
    std::string o = "{\"benchmark\": \"" + title_ + "\"";
    for (const auto& r : rows_) o += ", \"" + r.key + "\": " + r.json;
    return o + "}";
  }
  std::string table() const {
    size_t w = 0;
    for (const auto& r : rows_) w = std::max(w, r.key.size());
    std::string o = title_ + "\n";
    for (const auto& r : rows_) o += "  " + r.key + std::string(w - r.key.size(), ' ') + "  " + r.display + "\n";
    return o;
  }
  // Rows as (key, display) for documents.
  std::vector<std::pair<std::string, std::string>> rows() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& r : rows_) out.push_back({r.key, r.display});
    return out;
  }
  const std::string& title() const { return title_; }
  void print(bool asJson) const { std::fputs((asJson ? json() + "\n" : table()).c_str(), stdout); }

 private:
  struct Row { std::string key, json, display; };
  std::string title_;
  std::vector<Row> rows_;
};

}  // namespace invr
