#pragma once
/// JSON: values are nlohmann::ordered_json (Debian nlohmann-json3-dev; objects keep insertion
/// order), read with parse_json and written with json_text, refdyn's one JSON text format:
/// numbers as the shortest text that reads back as the same double (fmt), non-finite numbers
/// as null, strings escaped and always valid UTF-8 (a byte sequence that is not UTF-8 is
/// written as U+FFFD), one member or item per line up to a depth, then compact with ", ".
/// Never write JsonValue::dump(): its numbers and layout are not this format (dump(2, 2) even
/// compiles, with 2 taken as the indent character).

#include "refdyn/common/json_fwd.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>

namespace refdyn {

/// The JSON text of `v`. indent > 0: one member or item per line up to `depth` levels, then
/// compact; indent 0: compact (", " and ": " separators); indent < 0: minimal ("," and ":",
/// for large machine-read texts such as the report's data).
std::string json_text(const JsonValue& v, int indent = 2, int depth = 2);

/// Parses JSON text (nlohmann). Throws refdyn::Error "SOURCE: not valid JSON (...)".
JsonValue parse_json(std::string_view text, const std::string& source);

/// A JSON string literal of `s` (escaped, valid UTF-8).
std::string json_quote(std::string_view s);
/// True if `s` is valid UTF-8.
bool valid_utf8(std::string_view s);

}  // namespace refdyn
