#include "refdyn/common/json.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdint>
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

namespace {
void write(const JsonValue& v, std::string& out, int indent, int depth, int level) {
  const bool pretty = indent > 0 && level < depth;
  const std::string pad = pretty ? "\n" + std::string(static_cast<size_t>(indent * (level + 1)), ' ') : "";
  const std::string close_pad = pretty ? "\n" + std::string(static_cast<size_t>(indent * level), ' ') : "";
  const char* comma = pretty ? "," : indent < 0 ? "," : ", ";
  const char* colon = indent < 0 ? ":" : ": ";
  using T = JsonValue::value_t;
  switch (v.type()) {
    case T::null:
    case T::discarded: out += "null"; break;
    case T::boolean: out += v.get<bool>() ? "true" : "false"; break;
    case T::number_float: {
      const double x = v.get<double>();
      out += std::isfinite(x) ? fmt(x) : "null";
      break;
    }
    case T::number_integer: out += std::to_string(v.get<std::int64_t>()); break;
    case T::number_unsigned: out += std::to_string(v.get<std::uint64_t>()); break;
    case T::string: out += json_quote(v.get_ref<const std::string&>()); break;
    case T::binary: throw Error("json_text: binary values have no JSON text");
    case T::array: {
      out += "[";
      size_t i = 0;
      for (const auto& item : v) {
        out += i++ ? comma : "";
        out += pad;
        write(item, out, indent, depth, level + 1);
      }
      out += v.empty() ? "" : close_pad;
      out += "]";
      break;
    }
    case T::object: {
      out += "{";
      size_t i = 0;
      for (const auto& [key, item] : v.items()) {
        out += i++ ? comma : "";
        out += pad;
        out += json_quote(key) + colon;
        write(item, out, indent, depth, level + 1);
      }
      out += v.empty() ? "" : close_pad;
      out += "}";
      break;
    }
  }
}
}  // namespace

std::string json_text(const JsonValue& v, int indent, int depth) {
  std::string out;
  write(v, out, indent, depth, 0);
  return out;
}

JsonValue parse_json(std::string_view text, const std::string& source) {
  try {
    return JsonValue::parse(text.begin(), text.end());
  } catch (const nlohmann::json::parse_error& e) {
    std::string what = e.what();  // "[json.exception.parse_error.101] parse error at line 1, column 2: ..."
    const auto at = what.find("] ");
    if (at != std::string::npos) what = what.substr(at + 2);
    throw Error(source + ": not valid JSON (" + what + ")");
  }
}

}  // namespace refdyn
