#include "refdyn/common/json.hpp"

#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdio>

namespace refdyn {

namespace {
/// Length of the valid UTF-8 sequence starting at s[i], or 0.
size_t utf8_length(std::string_view s, size_t i) {
  const auto b = static_cast<unsigned char>(s[i]);
  size_t n;
  unsigned cp;
  if (b < 0x80) return 1;
  if ((b & 0xE0) == 0xC0) n = 2, cp = b & 0x1F;
  else if ((b & 0xF0) == 0xE0) n = 3, cp = b & 0x0F;
  else if ((b & 0xF8) == 0xF0) n = 4, cp = b & 0x07;
  else return 0;
  if (i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    const auto c = static_cast<unsigned char>(s[i + k]);
    if ((c & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (c & 0x3F);
  }
  // Overlong forms, surrogates and values past U+10FFFF are not UTF-8.
  if ((n == 2 && cp < 0x80) || (n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10FFFF ||
      (cp >= 0xD800 && cp <= 0xDFFF))
    return 0;
  return n;
}
}  // namespace

bool valid_utf8(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_length(s, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string json_quote(std::string_view s) {
  std::string o = "\"";
  for (size_t i = 0; i < s.size();) {
    const char c = s[i];
    const size_t n = utf8_length(s, i);
    if (n == 0) {
      o += "\\ufffd";
      ++i;
      continue;
    }
    if (n > 1) {
      o.append(s.substr(i, n));
      i += n;
      continue;
    }
    switch (c) {
      case '"': o += "\\\""; break;
      case '\\': o += "\\\\"; break;
      case '\n': o += "\\n"; break;
      case '\t': o += "\\t"; break;
      case '\r': o += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
          char b[8];
          std::snprintf(b, sizeof b, "\\u%04x", static_cast<unsigned char>(c));
          o += b;
        } else {
          o += c;
        }
    }
    ++i;
  }
  return o + "\"";
}

JsonValue& JsonValue::operator[](const std::string& key) {
  if (kind_ == Kind::Null) kind_ = Kind::Object;
  for (auto& [k, v] : members_)
    if (k == key) return v;
  members_.emplace_back(key, JsonValue());
  return members_.back().second;
}

JsonValue& JsonValue::push_back(JsonValue v) {
  if (kind_ == Kind::Null) kind_ = Kind::Array;
  items_.push_back(std::move(v));
  return items_.back();
}

std::string JsonValue::dump(int indent, int depth) const {
  std::string out;
  write(out, indent, depth, 0);
  return out;
}

void JsonValue::write(std::string& out, int indent, int depth, int level) const {
  const bool pretty = indent > 0 && level < depth;
  const std::string pad = pretty ? "\n" + std::string(static_cast<size_t>(indent * (level + 1)), ' ') : "";
  const std::string close_pad = pretty ? "\n" + std::string(static_cast<size_t>(indent * level), ' ') : "";
  switch (kind_) {
    case Kind::Null: out += "null"; break;
    case Kind::Bool: out += b_ ? "true" : "false"; break;
    case Kind::Number: out += std::isfinite(x_) ? fmt(x_) : "null"; break;
    case Kind::Integer:
      out += unsigned_ ? std::to_string(static_cast<unsigned long long>(i_)) : std::to_string(i_);
      break;
    case Kind::String: out += json_quote(s_); break;
    case Kind::Array:
      out += "[";
      for (size_t i = 0; i < items_.size(); ++i) {
        out += i ? (pretty ? "," : ", ") : "";
        out += pad;
        items_[i].write(out, indent, depth, level + 1);
      }
      out += items_.empty() ? "" : close_pad;
      out += "]";
      break;
    case Kind::Object:
      out += "{";
      for (size_t i = 0; i < members_.size(); ++i) {
        out += i ? (pretty ? "," : ", ") : "";
        out += pad;
        out += json_quote(members_[i].first) + ": ";
        members_[i].second.write(out, indent, depth, level + 1);
      }
      out += members_.empty() ? "" : close_pad;
      out += "}";
      break;
  }
}

}  // namespace refdyn
