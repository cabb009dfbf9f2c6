#pragma once
/// Result structs described once. A struct T that is written somewhere (summary.json, the CSV
/// tables, MPI payloads, Python dicts) specializes refdyn::Fields<T> with a tuple of its fields,
///
///   template <> struct Fields<RunSummary> {
///     static constexpr auto list() { return std::make_tuple(
///       field("t_end", &RunSummary::t_end, "s"), ...); }
///   };
///
/// each with its name, its member (or, for a derived value, a function of the struct), its unit,
/// the outputs it goes to (`in`) and, when they differ from the name, its JSON key and CSV column.
/// The writers (common/fields_json.hpp: JSON write and read; io/fields_csv.hpp: CSV headers and
/// rows; apps/mpi_run.cpp: MPI payloads; python/refdyn_module.cpp: dicts) walk this list: a
/// field added here appears in every output that lists it.
///
/// Values: double, long, int, bool, std::string, an enum with to_string(e) / from_string(s, e)
/// found by ADL, a described struct, std::vector of those, std::vector<std::pair<double, double>>,
/// named values std::vector<std::pair<std::string, V>> (an object keyed by the names, in their
/// order) and std::optional<V> (null when empty; absent with `| OmitIfEmpty{}`).

#include <optional>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace refdyn {

namespace sink {
/// The outputs a field goes to.
enum : unsigned {
  Json = 1u,    ///< summary.json, feasibility.json (and the Python dicts made from them)
  Csv = 2u,     ///< sweep.csv, variants.csv
  Wire = 4u,    ///< MPI payloads between ranks (stored members only, bit-exact)
  Python = 8u,  ///< the dicts of the Python bindings
  Stat = 16u,   ///< summary.json "statistics": a distribution over the runs
  All = Json | Csv | Wire | Python,
};
}  // namespace sink

/// Conditions a writer states (FieldContext::holds) for fields that depend on them.
namespace when {
enum : unsigned {
  Tracked = 1u,  ///< closed-loop runs were tracked (the run columns exist)
  Ran = 2u,      ///< the record's plan ran (a variant that is a valid scenario)
  HasRuns = 4u,  ///< the record has at least one run
  Incomplete = 8u,  ///< a feasibility report whose plan did not reach its end
};
}  // namespace when

/// A stored member.
template <class T, class M>
struct MemberField {
  using Owner = T;
  using Value = M;
  static constexpr bool stored = true;
  const char* name;               ///< the Python key, and the JSON key / CSV column unless set below
  M T::*member;
  const char* unit = "";          ///< SI unit of the value ("" for counts, text, flags)
  unsigned in = sink::All;         ///< outputs (sink::…)
  const char* json = nullptr;     ///< JSON key; may hold "{late}" (FieldContext::late)
  const char* csv = nullptr;      ///< CSV column (or, for a per-joint field, its prefix before "_<joint>")
  int csv_block = 0;              ///< CSV columns go by block (0, 1, 2: free text last), then by this order
  unsigned only_if = 0;           ///< written only when the writer's conditions hold these (when::…)
  unsigned valid_if = 0;          ///< CSV: the cell is empty ("nan" for numbers) unless these hold
  const char* label = nullptr;    ///< vector of structs in JSON: each object starts with label: name of element j
  bool omit_empty = false;        ///< an empty std::optional is left out (else it is null)
  const M& get(const T& x) const { return x.*member; }
  M& ref(T& x) const { return x.*member; }
  const char* key() const { return json ? json : name; }
  const char* column() const { return csv ? csv : name; }
};

/// A value derived from the struct (written, never read back).
template <class T, class R>
struct DerivedField {
  using Owner = T;
  using Value = R;
  static constexpr bool stored = false;
  const char* name;
  R (*fn)(const T&);
  const char* unit = "";
  unsigned in = sink::Json;
  const char* json = nullptr;
  const char* csv = nullptr;
  int csv_block = 0;
  unsigned only_if = 0;
  unsigned valid_if = 0;
  const char* label = nullptr;
  bool omit_empty = false;
  R get(const T& x) const { return fn(x); }
  const char* key() const { return json ? json : name; }
  const char* column() const { return csv ? csv : name; }
};

template <class T, class M>
constexpr MemberField<T, M> field(const char* name, M T::*member, const char* unit = "", unsigned in = sink::All) {
  return {name, member, unit, in};
}
template <class T, class R>
constexpr DerivedField<T, R> derived(const char* name, R (*fn)(const T&), const char* unit = "", unsigned in = sink::Json) {
  return {name, fn, unit, in};
}
/// Builder-style modifiers: field(...) | json_key("x") | csv_column("y") | …
struct JsonKey { const char* key; };
struct CsvColumn { const char* column; int block = 0; };
struct OnlyIf { unsigned bits; };
struct ValidIf { unsigned bits; };
struct Label { const char* name; };
struct OmitIfEmpty {};
template <class F> constexpr F operator|(F f, JsonKey k) { f.json = k.key; return f; }
template <class F> constexpr F operator|(F f, CsvColumn c) { if (c.column) f.csv = c.column; f.csv_block = c.block; return f; }
template <class F> constexpr F operator|(F f, OnlyIf c) { f.only_if = c.bits; return f; }
template <class F> constexpr F operator|(F f, ValidIf c) { f.valid_if = c.bits; return f; }
template <class F> constexpr F operator|(F f, Label l) { f.label = l.name; return f; }
template <class F> constexpr F operator|(F f, OmitIfEmpty) { f.omit_empty = true; return f; }

template <class V>
struct is_optional : std::false_type {};
template <class V>
struct is_optional<std::optional<V>> : std::true_type {};
/// std::vector<std::pair<std::string, V>>: named values
template <class V>
struct is_named : std::false_type {};
template <class V>
struct is_named<std::vector<std::pair<std::string, V>>> : std::true_type {};

/// True when the field's value is an empty std::optional that the field leaves out.
template <class F, class T>
bool omitted(const F& f, const T& x) {
  if constexpr (is_optional<std::decay_t<decltype(f.get(x))>>::value) return f.omit_empty && !f.get(x).has_value();
  else return false;
}

/// Specialized for every described struct: static constexpr auto list() → tuple of fields.
template <class T>
struct Fields;

template <class T, class = void>
struct is_described : std::false_type {};
template <class T>
struct is_described<T, std::void_t<decltype(Fields<T>::list())>> : std::true_type {};
template <class T>
inline constexpr bool is_described_v = is_described<T>::value;

/// What a writer knows beyond the struct: which conditions hold (when::…), the text of the
/// "{late}" placeholder in keys, and the names of the elements of labelled vectors (joints).
struct FieldContext {
  unsigned holds = 0;
  std::string late;
  const std::vector<std::string>* names = nullptr;
  /// `key` with "{late}" replaced.
  std::string expand(const char* key) const {
    std::string k = key;
    const auto at = k.find("{late}");
    if (at != std::string::npos) k.replace(at, 6, late);
    return k;
  }
  bool allows(unsigned only_if) const { return (holds & only_if) == only_if; }
};

/// Calls f(field) for every field of T, in the order listed.
template <class T, class F>
constexpr void for_each_field(F&& f) {
  std::apply([&](const auto&... fs) { (f(fs), ...); }, Fields<T>::list());
}

}  // namespace refdyn
