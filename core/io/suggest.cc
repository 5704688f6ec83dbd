#include "core/io/suggest.h"

#include <algorithm>
#include <cctype>

namespace invr {

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Optimal string alignment distance: insertions, deletions, substitutions and swaps of two
// neighbouring characters (the commonest typo) each cost 1.
size_t editDistance(const std::string& a, const std::string& b) {
  const size_t n = a.size(), m = b.size();
  std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
  for (size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (size_t i = 1; i <= n; ++i)
    for (size_t j = 1; j <= m; ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[n][m];
}

}  // namespace

std::vector<std::string> closestNames(const std::string& given, const std::vector<std::string>& known, size_t max) {
  const std::string g = lower(given);
  if (g.empty() || g.size() > 256) return {};
  std::vector<std::pair<size_t, std::string>> scored;
  for (const auto& k : known) {
    const std::string l = lower(k);
    if (l.size() > 256) continue;
    const size_t d = editDistance(g, l);
    const bool contains = std::min(g.size(), l.size()) >= 3 && (l.find(g) != std::string::npos || g.find(l) != std::string::npos);
    if (d <= std::max<size_t>(1, std::max(g.size(), l.size()) / 3) || contains) scored.emplace_back(contains ? std::min<size_t>(d, 1) : d, k);
  }
  std::stable_sort(scored.begin(), scored.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<std::string> out;
  for (const auto& s : scored) {
    if (out.size() == max) break;
    if (std::find(out.begin(), out.end(), s.second) == out.end()) out.push_back(s.second);
  }
  return out;
}

std::string didYouMean(const std::string& given, const std::vector<std::string>& known) {
  const auto names = closestNames(given, known);
  if (names.empty()) return "";
  std::string s = "; did you mean ";
  for (size_t i = 0; i < names.size(); ++i) s += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + ("'" + names[i] + "'");
  return s + "?";
}

}  // namespace invr
