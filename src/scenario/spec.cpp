#include "refdyn/scenario/spec.hpp"

namespace refdyn {

namespace {
const SpecValue& null_value() {
  static const SpecValue v;
  return v;
}
}  // namespace

const SpecValue& SpecValue::operator[](const std::string& key) const {
  if (is_map())
    for (const auto& e : entries)
      if (e.key == key) return e.value;
  return null_value();
}

const SpecValue& SpecValue::operator[](size_t i) const {
  return is_list() && i < items.size() ? items[i] : null_value();
}

SourceLocation SpecValue::key_location(const std::string& key) const {
  if (is_map())
    for (const auto& e : entries)
      if (e.key == key) return {where.file, e.key_line};
  return where;
}

std::string SpecValue::describe() const {
  switch (kind) {
    case Kind::Null: return "nothing";
    case Kind::Scalar: return "'" + text + "'";
    case Kind::List: return "a list";
    case Kind::Map: return "a mapping";
  }
  return "?";
}

SpecValue SpecValue::scalar(std::string text, SourceLocation where) {
  SpecValue v;
  v.kind = Kind::Scalar;
  v.text = std::move(text);
  v.where = std::move(where);
  return v;
}

}  // namespace refdyn
