#pragma once
/// The JSON value type without nlohmann's full header (for declarations): JsonValue is
/// nlohmann::ordered_json, an ordered JSON value (objects keep insertion order).
#include <nlohmann/json_fwd.hpp>

namespace refdyn {
using JsonValue = nlohmann::ordered_json;
}  // namespace refdyn
