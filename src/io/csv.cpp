#include "refdyn/io/csv.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/io/scenario.hpp"

#include <cstdlib>

namespace refdyn::io {

std::string csv_text(const std::string& x) {
  if (x.find_first_of(",\"\r\n") == std::string::npos) return x;
  std::string q = "\"";
  for (char ch : x) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

std::string csv_line(const std::vector<std::string>& cells) {
  std::string s;
  for (size_t i = 0; i < cells.size(); ++i) s += (i ? "," : "") + cells[i];
  return s + "\n";
}

int CsvText::column(const std::string& name) const {
  for (size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return static_cast<int>(i);
  return -1;
}

CsvText parse_csv(std::string_view text, const std::string& source) {
  CsvText t;
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false, any = false, header_done = false;
  size_t line = 1, first_line = 1;
  auto end_row = [&] {
    if (!any && cells.empty() && cell.empty()) return;  // a blank line
    cells.push_back(std::move(cell));
    cell.clear();
    if (!header_done) {
      t.header = std::move(cells);
      header_done = true;
    } else {
      if (cells.size() != t.header.size())
        throw Error(source + ":" + std::to_string(first_line) + ": expected " + std::to_string(t.header.size()) +
                    " values, got " + std::to_string(cells.size()));
      t.rows.push_back(std::move(cells));
      t.lines.push_back(first_line);
    }
    cells.clear();
    any = false;
  };
  for (size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (!any && cells.empty() && cell.empty()) first_line = line;
    if (quoted) {
      if (ch == '"' && i + 1 < text.size() && text[i + 1] == '"') cell += '"', ++i;
      else if (ch == '"') quoted = false;
      else {
        if (ch == '\n') ++line;
        cell += ch;
      }
      continue;
    }
    if (ch == '"') quoted = any = true;
    else if (ch == ',') cells.push_back(std::move(cell)), cell.clear(), any = true;
    else if (ch == '\r' && i + 1 < text.size() && text[i + 1] == '\n') continue;
    else if (ch == '\n') end_row(), ++line;
    else cell += ch, any = true;
  }
  if (quoted) throw Error(source + ":" + std::to_string(first_line) + ": unterminated quoted value");
  end_row();
  return t;
}

CsvTable parse_csv_numbers(std::string_view text, const std::string& source) {
  const CsvText cells = parse_csv(text, source);
  CsvTable t;
  t.header = cells.header;
  t.rows.reserve(cells.rows.size());
  for (size_t r = 0; r < cells.rows.size(); ++r) {
    std::vector<double> row;
    row.reserve(cells.rows[r].size());
    for (const std::string& c : cells.rows[r]) {
      char* e = nullptr;
      const double v = std::strtod(c.c_str(), &e);
      if (c.empty() || *e != '\0')
        throw Error(source + ":" + std::to_string(cells.lines[r]) + ": expected numbers separated by commas");
      row.push_back(v);
    }
    t.rows.push_back(std::move(row));
  }
  return t;
}

CsvTable read_csv_numbers(const std::string& path) {
  const std::string text = read_text_file(path, "results file", std::size_t(1) << 30);
  CsvTable t = parse_csv_numbers(text, path);
  if (t.header.empty() || t.rows.empty()) throw Error(path + ": no samples in it");
  return t;
}

}  // namespace refdyn::io
