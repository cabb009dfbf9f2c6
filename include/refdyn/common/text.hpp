#pragma once
/// Small text helpers shared by error messages.
#include <string>
#include <vector>

namespace refdyn {

/// Levenshtein edit distance.
int edit_distance(const std::string& a, const std::string& b);
/// " (did you mean 'x'?)" for the closest candidate within a small distance, else the list of
/// valid names: " (valid: a, b, c)".
std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates);
/// The one name lookup: the index of `name` in `names`, else throws refdyn::Error
/// "unknown WHAT 'name' (did you mean 'x'?)" + hint.
int find_name(const std::vector<std::string>& names, const std::string& name, const std::string& what,
              const std::string& hint = {});
/// Formats a double with up to 17 significant digits, shortest round-trip.
std::string fmt(double x);

}  // namespace refdyn
