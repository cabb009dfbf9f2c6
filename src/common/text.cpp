#include "refdyn/common/text.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>

#include "refdyn/common/error.hpp"

namespace refdyn {

int edit_distance(const std::string& a, const std::string& b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      int sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates) {
  if (candidates.empty()) return " (there are none defined)";
  int best = 1 << 30;
  const std::string* best_name = nullptr;
  for (const auto& c : candidates) {
    int d = edit_distance(word, c);
    if (d < best) {
      best = d;
      best_name = &c;
    }
  }
  int allowed = std::max<int>(2, static_cast<int>(word.size()) / 3);
  if (best_name && best <= allowed) return " (did you mean '" + *best_name + "'?)";
  std::string s = " (valid: ";
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (i) s += ", ";
    s += candidates[i];
  }
  return s + ")";
}

std::string fmt(double x) {
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

int find_name(const std::vector<std::string>& names, const std::string& name, const std::string& what,
              const std::string& hint) {
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return static_cast<int>(i);
  throw Error("unknown " + what + " '" + name + "'" + did_you_mean(name, names) + hint);
}

}  // namespace refdyn
