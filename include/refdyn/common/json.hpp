#pragma once
/// The one JSON writer: an ordered JSON value (objects keep insertion order) and its text.
/// Strings are escaped (quotes, backslashes, control characters) and always valid UTF-8 in the
/// output: a byte sequence that is not UTF-8 is written as U+FFFD. Non-finite numbers are null.

#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace refdyn {

class JsonValue {
 public:
  enum class Kind { Null, Bool, Number, Integer, String, Array, Object };
  JsonValue() = default;
  JsonValue(std::nullptr_t) {}
  JsonValue(bool b) : kind_(Kind::Bool), b_(b) {}
  JsonValue(double x) : kind_(Kind::Number), x_(x) {}
  JsonValue(int i) : kind_(Kind::Integer), i_(i) {}
  JsonValue(long i) : kind_(Kind::Integer), i_(i) {}
  JsonValue(long long i) : kind_(Kind::Integer), i_(i) {}
  JsonValue(unsigned long i) : kind_(Kind::Integer), i_(static_cast<long long>(i)), unsigned_(true) {}
  JsonValue(unsigned long long i) : kind_(Kind::Integer), i_(static_cast<long long>(i)), unsigned_(true) {}
  JsonValue(std::string s) : kind_(Kind::String), s_(std::move(s)) {}
  JsonValue(const char* s) : kind_(Kind::String), s_(s) {}
  static JsonValue array() { JsonValue v; v.kind_ = Kind::Array; return v; }
  static JsonValue object() { JsonValue v; v.kind_ = Kind::Object; return v; }

  Kind kind() const { return kind_; }
  /// Object member (inserted at the end if new; a Null value becomes an object).
  JsonValue& operator[](const std::string& key);
  /// Appends to an array (a Null value becomes an array).
  JsonValue& push_back(JsonValue v);
  /// Array element i (throws std::out_of_range).
  JsonValue& at(size_t i) { return items_.at(i); }
  size_t size() const { return kind_ == Kind::Array ? items_.size() : members_.size(); }

  /// The JSON text. indent > 0: one member or item per line up to `depth` levels, then compact.
  std::string dump(int indent = 2, int depth = 2) const;

 private:
  void write(std::string& out, int indent, int depth, int level) const;
  Kind kind_ = Kind::Null;
  bool b_ = false;
  double x_ = 0;
  long long i_ = 0;
  bool unsigned_ = false;  ///< i_ holds an unsigned value (written exactly up to 2^64 − 1)
  std::string s_;
  std::vector<JsonValue> items_;
  std::vector<std::pair<std::string, JsonValue>> members_;
};

/// A JSON string literal of `s` (escaped, valid UTF-8).
std::string json_quote(std::string_view s);
/// True if `s` is valid UTF-8.
bool valid_utf8(std::string_view s);

}  // namespace refdyn
