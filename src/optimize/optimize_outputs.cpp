// refdyn optimize's outputs (docs/optimize.md): summary.json's section, optimization.csv and
// optimized.yaml (the scenario rewritten at the values found).
#include "evaluator.hpp"

#include "refdyn/common/fields_json.hpp"
#include "refdyn/io/csv.hpp"

namespace refdyn {

using optimize_detail::list_element;

JsonValue OptimizeSummary::to_json() const { return refdyn::to_json(*this); }

std::string optimization_csv(const OptimizeSummary& s) {
  const FieldContext c;
  const io::ColumnLists lists{{"x", &s.variables}, {"constraints", &s.constraint_names}};
  std::vector<std::string> head;
  io::csv_columns<OptimizeEvaluation>(head, c, &lists);
  std::string out = io::csv_line(head);
  for (const OptimizeEvaluation& r : s.history) {
    std::vector<std::string> cells;
    io::csv_cells(cells, r, c, &lists);
    out += io::csv_line(cells);
  }
  return out;
}

std::string optimized_yaml(const std::string& text, const SpecValue& root, const std::vector<std::string>& names,
                           const std::vector<double>& values) {
  const SpecValue& params = root["parameters"];
  std::vector<size_t> line_start{0};
  for (size_t i = 0; i < text.size(); ++i)
    if (text[i] == '\n') line_start.push_back(i + 1);
  struct Edit {
    size_t at, length;
    std::string with;
  };
  std::vector<Edit> edits;
  edits.reserve(names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    size_t element = 0;
    const std::string list = list_element(names[i], element);
    const SpecValue& p = params[list.empty() ? names[i] : list];
    const SpecValue& v = list.empty() ? p : p[element];
    if (!v.is_scalar() || (!list.empty() && !p.is_list()))
      throw Error("optimized.yaml: the parameter '" + names[i] + "' was not found as a value in the parameters: section");
    const SourceLocation& w = v.where;
    if (w.line < 1 || static_cast<size_t>(w.line) > line_start.size() || w.column < 1)
      throw Error("optimized.yaml: the parameter '" + names[i] + "' has no recorded location");
    const size_t at = line_start[static_cast<size_t>(w.line - 1)] + static_cast<size_t>(w.column - 1);
    const size_t eol = std::min(text.find('\n', at), text.size());
    size_t length = 0;
    if (at < text.size() && (text[at] == '"' || text[at] == '\'') && text.find(text[at], at + 1) < eol)
      length = text.find(text[at], at + 1) + 1 - at;  // a quoted value: the quotes go too
    else if (text.compare(at, v.text.size(), v.text) == 0 && at + v.text.size() <= eol)
      length = v.text.size();
    else
      throw Error(w.file + ":" + std::to_string(w.line) + ": parameters." + names[i] +
                  ": optimized.yaml rewrites values in place, and this one is not a plain one-line value (hint: write it as a number)");
    std::string with = fmt(values[i]);
    // keep a comment where it was: pad or shrink the spaces between the value and a '#'
    size_t after = at + length, c = after;
    while (c < eol && (text[c] == ' ' || text[c] == '\t')) ++c;
    if (c < eol && text[c] == '#' && c > after) {
      const long pad = static_cast<long>(c - at) - static_cast<long>(with.size());
      with += std::string(static_cast<size_t>(std::max(1L, pad)), ' ');
      length = c - at;
    }
    edits.push_back({at, length, std::move(with)});
  }
  std::sort(edits.begin(), edits.end(), [](const Edit& x, const Edit& y) { return x.at < y.at; });
  std::string out;
  out.reserve(text.size() + 16 * edits.size());
  size_t pos = 0;
  for (const Edit& e : edits) {
    if (e.at < pos) throw Error("optimized.yaml: two variables share one value in the text");
    out.append(text, pos, e.at - pos);
    out += e.with;
    pos = e.at + e.length;
  }
  out.append(text, pos, std::string::npos);
  if (!out.empty() && out.back() != '\n') out += '\n';
  return out;
}

std::string optimized_yaml(const std::string& text, const std::vector<std::string>& names, const std::vector<double>& values) {
  return optimized_yaml(text, io::parse_yaml_tree(text, "optimized.yaml"), names, values);
}

}  // namespace refdyn

