#pragma once
/// CSV: the columns and cells of described structs (common/fields.hpp) for sweep.csv and
/// variants.csv, and the one CSV reader (RFC 4180 quotes) of every refdyn table.

#include "refdyn/common/fields.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/io/output.hpp"

#include <cmath>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace refdyn::io {

/// A CSV text field (RFC 4180): quoted when it holds a comma, a quote or a line break.
std::string csv_text(const std::string& x);
/// A number cell: the shortest round-trip text, "nan" when not finite.
inline std::string csv_number(double x) { return std::isfinite(x) ? fmt(x) : std::string("nan"); }

/// A CSV file as text cells: header and rows (RFC 4180: quoted cells, "" inside quotes; CR LF
/// or LF; blank lines skipped). Every row has the header's number of cells, else
/// refdyn::Error "SOURCE:LINE: expected N values, got M".
struct CsvText {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<size_t> lines;  ///< the line of each row (for messages)
  /// Column index of `name`, or -1.
  int column(const std::string& name) const;
};
CsvText parse_csv(std::string_view text, const std::string& source);
/// The table of numbers of a CSV written by refdyn (CsvTable::to_string): every cell a number
/// ("nan" for non-finite), else refdyn::Error "SOURCE:LINE: expected numbers separated by commas".
CsvTable parse_csv_numbers(std::string_view text, const std::string& source);
/// parse_csv_numbers of a file (at most 1 GiB); also "SOURCE: no samples in it" for a table without rows.
CsvTable read_csv_numbers(const std::string& path);

/// Column names a writer gives to vector fields of numbers, by field name: each such field has
/// one column per listed name (the name itself, as CSV text), e.g. optimization.csv's variables
/// and constraints. Other vector fields are per joint (FieldContext::names).
using ColumnLists = std::vector<std::pair<std::string, const std::vector<std::string>*>>;

namespace detail {
template <class V>
std::string csv_cell(const V& v) {
  if constexpr (std::is_same_v<V, double>) return csv_number(v);
  else if constexpr (std::is_same_v<V, long>) return std::to_string(v);
  else if constexpr (std::is_same_v<V, bool>) return v ? "1" : "0";
  else if constexpr (std::is_same_v<V, std::string>) return csv_text(v);
  else return to_string(v);
}
template <class V>
inline constexpr bool is_number_v = std::is_same_v<V, double>;
/// The list naming the columns of the vector field `name` (ColumnLists), or null.
inline const std::vector<std::string>* listed(const ColumnLists* lists, const char* name) {
  if (lists)
    for (const auto& [field, names] : *lists)
      if (field == name) return names;
  return nullptr;
}
template <class V>
struct is_struct_vector : std::false_type {};
template <class E>
struct is_struct_vector<std::vector<E>> : std::bool_constant<is_described_v<E>> {};
}  // namespace detail

/// Appends the CSV columns of T (its fields with sink::Csv, by csv_block, then in order; a
/// per-joint field `x` gives x_<joint> for every name in c.names, a vector of structs one
/// group per field of the struct; a vector field of `lists`: the listed names).
template <class T>
void csv_columns(std::vector<std::string>& cols, const FieldContext& c, const ColumnLists* lists = nullptr) {
  for (int block = 0; block < 3; ++block)
    for_each_field<T>([&](const auto& f) {
      using V = typename std::decay_t<decltype(f)>::Value;
      if (!(f.in & sink::Csv) || f.csv_block != block || !c.allows(f.only_if)) return;
      if constexpr (std::is_same_v<V, std::vector<double>>) {
        if (const std::vector<std::string>* names = detail::listed(lists, f.name)) {
          for (const auto& n : *names) cols.push_back(csv_text(n));
          return;
        }
        for (const auto& j : *c.names) cols.push_back(std::string(f.column()) + "_" + j);
      } else if constexpr (detail::is_struct_vector<V>::value) {
        for_each_field<typename V::value_type>([&](const auto& g) {
          if (!(g.in & sink::Csv)) return;
          for (const auto& j : *c.names) cols.push_back(std::string(g.column()) + "_" + j);
        });
      } else {
        cols.push_back(f.column());
      }
    });
}

/// Appends the cells of `x`, in the order of csv_columns<T>. A field whose valid_if conditions
/// do not hold is an empty cell ("nan" for a number).
template <class T>
void csv_cells(std::vector<std::string>& cells, const T& x, const FieldContext& c, const ColumnLists* lists = nullptr) {
  for (int block = 0; block < 3; ++block)
    for_each_field<T>([&](const auto& f) {
      using V = typename std::decay_t<decltype(f)>::Value;
      if (!(f.in & sink::Csv) || f.csv_block != block || !c.allows(f.only_if)) return;
      const bool valid = c.allows(f.valid_if);
      if constexpr (std::is_same_v<V, std::vector<double>>) {
        const auto& v = f.get(x);
        const std::vector<std::string>* names = detail::listed(lists, f.name);
        const size_t n = names ? names->size() : c.names->size();
        for (size_t j = 0; j < n; ++j) cells.push_back(valid && j < v.size() ? csv_number(v[j]) : "nan");
      } else if constexpr (detail::is_struct_vector<V>::value) {
        const auto& v = f.get(x);
        for_each_field<typename V::value_type>([&](const auto& g) {
          if (!(g.in & sink::Csv)) return;
          for (size_t j = 0; j < c.names->size(); ++j)
            cells.push_back(valid && j < v.size() ? detail::csv_cell(g.get(v[j])) : "nan");
        });
      } else if (!valid) {
        cells.push_back(detail::is_number_v<V> ? "nan" : "");
      } else {
        cells.push_back(detail::csv_cell(f.get(x)));
      }
    });
}

/// One CSV line of cells.
std::string csv_line(const std::vector<std::string>& cells);

}  // namespace refdyn::io
