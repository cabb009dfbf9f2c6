// symbolic_number and SymbolicInputs (symbolic_form.hpp): texts of numbers for the symbolic forms
// that constraints, force elements and functions of time give the code generator.
#include "refdyn/expression/symbolic_form.hpp"

#include <cctype>
#include <cstdio>
#include <map>

namespace refdyn {

std::string symbolic_number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  std::string s = buf;
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // keep it a decimal (not inf/nan)
  return v < 0 ? "(" + s + ")" : s;
}

namespace {

/// Replaces the whole number tokens `token` of `text` by `by`.
std::string replace_number(const std::string& text, const std::string& token, const std::string& by) {
  auto number_char = [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)) || ch == '.'; };
  std::string out;
  std::size_t from = 0;
  for (std::size_t at = text.find(token); at != std::string::npos; at = text.find(token, at + 1)) {
    const bool starts = at == 0 || !(number_char(text[at - 1]) || std::isalpha(static_cast<unsigned char>(text[at - 1])) ||
                                     text[at - 1] == '_');
    const std::size_t end = at + token.size();
    const bool ends = end == text.size() || !(number_char(text[end]) || text[end] == 'e' || text[end] == 'E');
    if (!starts || !ends) continue;
    out += text.substr(from, at - from) + by;
    from = end;
  }
  return out + text.substr(from);
}

}  // namespace

void SymbolicInputs::apply(SymbolicForm& form) const {
  std::map<double, std::string> names;
  std::map<double, bool> ambiguous;
  for (const auto& [v, text] : recorded) {
    const auto it = names.find(v);
    if (it == names.end()) names[v] = text;
    else if (it->second != text) ambiguous[v] = true;
  }
  bool used = false;
  for (const auto& [v, text] : names) {
    if (ambiguous.count(v)) continue;
    const std::string token = symbolic_number(v), by = "(" + text + ")";
    auto fix = [&](std::string& s) {
      const std::string r = replace_number(s, token, by);
      used = used || r != s;
      s = r;
    };
    for (auto& r : form.rows) fix(r);
    for (auto& r : form.state_rates) fix(r);
    for (auto& [name, f] : form.functions) fix(f);
  }
  if (used)
    for (const auto& [name, v] : parameters) form.parameters.emplace(name, v);
}

}  // namespace refdyn
