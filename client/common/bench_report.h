// Benchmarks print a readable table, or with --json one JSON object with the named figures.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace invr {

class BenchReport {
 public:
  // Keys keep the order they were added in.
  using Json = nlohmann::ordered_json;

  explicit BenchReport(std::string title) : title_(std::move(title)) {}
  void text(const std::string& key, const std::string& value) { rows_.push_back({key, Json(value), value}); }
  void number(const std::string& key, double value, const std::string& unit = "") {
    rows_.push_back({key, Json(value), fmt(value) + (unit.empty() ? "" : " " + unit)});
  }
  // Any JSON value (e.g. an object of figures) with its table display.
  void value(const std::string& key, Json json, const std::string& display) { rows_.push_back({key, std::move(json), display}); }
  // Figures as the table and the JSON print them: 6 significant digits; null if not finite.
  static std::string fmt(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
  }
  // `j` on one line with ", " and ": " separators, floating-point numbers as fmt() prints them;
  // nlohmann writes the strings (escaped; bytes that are not UTF-8 become U+FFFD) and integers.
  static std::string line(const Json& j) {
    std::string o;
    switch (j.type()) {
      case Json::value_t::object:
        for (const auto& [k, v] : j.items()) o += (o.empty() ? "" : ", ") + line(Json(k)) + ": " + line(v);
        return "{" + o + "}";
      case Json::value_t::array:
        for (const auto& v : j) o += (o.empty() ? "" : ", ") + line(v);
        return "[" + o + "]";
      case Json::value_t::number_float:
        return fmt(j.get<double>());
      default:
        return j.dump(-1, ' ', false, Json::error_handler_t::replace);
    }
  }
  // {"benchmark": title, then the figures in the order they were added}.
  Json toJson() const {
    Json o = {{"benchmark", title_}};
    for (const auto& r : rows_) o[r.key] = r.json;
    return o;
  }
  std::string json() const { return line(toJson()); }
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
  struct Row {
    std::string key;
    Json json;
    std::string display;
  };
  std::string title_;
  std::vector<Row> rows_;
};

}  // namespace invr
