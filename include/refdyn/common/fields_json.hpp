#pragma once
/// JSON of described structs (common/fields.hpp): to_json writes the fields that go to
/// sink::Json (in their order; keys with "{late}" expanded), from_json reads the stored ones
/// back (null → NaN for numbers, an empty std::optional). Named values
/// (std::vector<std::pair<std::string, V>>) are an object. The one JSON path of RunSummary, VariantSummary, IntegrationSummary, the
/// feasibility report and OptimizeSummary.

#include "refdyn/common/error.hpp"
#include "refdyn/common/fields.hpp"
#include "refdyn/common/json.hpp"

#include <cmath>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace refdyn {

template <class T>
void write_fields_json(JsonValue& o, const T& x, const FieldContext& c, unsigned in = sink::Json);
template <class T>
void read_fields_json(const JsonValue& j, T& x, const FieldContext& c, const std::string& where);

namespace detail {
template <class V>
struct is_vector : std::false_type {};
template <class E>
struct is_vector<std::vector<E>> : std::true_type {};

template <class V>
JsonValue json_of(const V& v, const FieldContext& c, const char* label, unsigned in) {
  if constexpr (std::is_same_v<V, double> || std::is_same_v<V, long> || std::is_same_v<V, bool> ||
                std::is_same_v<V, std::string>) {
    return JsonValue(v);
  } else if constexpr (std::is_same_v<V, int>) {
    return JsonValue(static_cast<long>(v));
  } else if constexpr (is_optional<V>::value) {
    return v ? json_of(*v, c, label, in) : JsonValue();
  } else if constexpr (std::is_enum_v<V>) {
    return JsonValue(to_string(v));
  } else if constexpr (std::is_same_v<V, std::pair<double, double>>) {
    JsonValue a = JsonValue::array();
    a.push_back(v.first);
    a.push_back(v.second);
    return a;
  } else if constexpr (is_described_v<V>) {
    JsonValue o = JsonValue::object();
    write_fields_json(o, v, c, in);
    return o;
  } else if constexpr (is_named<V>::value) {
    JsonValue o = JsonValue::object();  // named values: an object, in their order
    for (const auto& [name, x] : v) o[name] = json_of(x, c, nullptr, in);
    return o;
  } else {
    static_assert(is_vector<V>::value, "a field of a type the JSON writer does not know");
    JsonValue a = JsonValue::array();
    for (size_t j = 0; j < v.size(); ++j) {
      JsonValue e = json_of(v[j], c, nullptr, in);
      if (label && c.names) {
        JsonValue o = JsonValue::object();
        o[label] = j < c.names->size() ? (*c.names)[j] : std::string();
        for (auto& [k, item] : e.items()) o[k] = std::move(item);
        e = std::move(o);
      }
      a.push_back(std::move(e));
    }
    return a;
  }
}

template <class V>
void read_json(const JsonValue& j, V& v, const FieldContext& c, const std::string& where) {
  if constexpr (std::is_same_v<V, double>) {
    if (j.is_null()) v = std::nan("");
    else if (j.is_number()) v = j.get<double>();
    else throw Error(where + ": expected a number");
  } else if constexpr (std::is_same_v<V, long> || std::is_same_v<V, int>) {
    if (!j.is_number_integer()) throw Error(where + ": expected an integer");
    v = static_cast<V>(j.get<long>());
  } else if constexpr (is_optional<V>::value) {
    if (j.is_null()) {
      v.reset();
    } else {
      v.emplace();
      read_json(j, *v, c, where);
    }
  } else if constexpr (std::is_same_v<V, bool>) {
    if (!j.is_boolean()) throw Error(where + ": expected true or false");
    v = j.get<bool>();
  } else if constexpr (std::is_same_v<V, std::string>) {
    if (!j.is_string()) throw Error(where + ": expected a string");
    v = j.get<std::string>();
  } else if constexpr (std::is_enum_v<V>) {
    if (!j.is_string() || !from_string(j.get<std::string>(), v)) throw Error(where + ": unknown value " + json_text(j, 0));
  } else if constexpr (std::is_same_v<V, std::pair<double, double>>) {
    if (!j.is_array() || j.size() != 2) throw Error(where + ": expected [a, b]");
    read_json(j[0], v.first, c, where);
    read_json(j[1], v.second, c, where);
  } else if constexpr (is_described_v<V>) {
    read_fields_json(j, v, c, where);
  } else if constexpr (is_named<V>::value) {
    if (!j.is_object()) throw Error(where + ": expected an object");
    v.clear();
    for (const auto& [name, x] : j.items()) {
      v.emplace_back(name, typename V::value_type::second_type{});
      read_json(x, v.back().second, c, where + "." + name);
    }
  } else {
    if (!j.is_array()) throw Error(where + ": expected an array");
    v.resize(j.size());
    for (size_t k = 0; k < j.size(); ++k) read_json(j[k], v[k], c, where + "[" + std::to_string(k) + "]");
  }
}
}  // namespace detail

/// Adds the fields of `x` that go to `in` (sink::Json) to the object `o`, in their order.
template <class T>
void write_fields_json(JsonValue& o, const T& x, const FieldContext& c, unsigned in) {
  for_each_field<T>([&](const auto& f) {
    if (!(f.in & in) || !c.allows(f.only_if) || omitted(f, x)) return;
    o[c.expand(f.key())] = detail::json_of(f.get(x), c, f.label, in);
  });
}

/// The JSON object of `x`.
template <class T>
JsonValue to_json(const T& x, const FieldContext& c = {}, unsigned in = sink::Json) {
  JsonValue o = JsonValue::object();
  write_fields_json(o, x, c, in);
  return o;
}

/// Reads the stored fields of T that go to JSON from the object `j` (fields whose key is
/// absent keep their value: a record written without them, e.g. no runs tracked).
template <class T>
void read_fields_json(const JsonValue& j, T& x, const FieldContext& c, const std::string& where) {
  if (!j.is_object()) throw Error(where + ": expected an object");
  for_each_field<T>([&](const auto& f) {
    if constexpr (std::decay_t<decltype(f)>::stored) {
      if (!(f.in & sink::Json)) return;
      const std::string key = c.expand(f.key());
      const auto it = j.find(key);
      if (it == j.end()) return;
      detail::read_json(*it, f.ref(x), c, where + "." + key);
    }
  });
}

template <class T>
T from_json(const JsonValue& j, const FieldContext& c = {}) {
  T x{};
  read_fields_json(j, x, c, "JSON");
  return x;
}

}  // namespace refdyn
