#pragma once
// Private to src/constraints/ (not installed): what the kinds' files share besides law.hpp.
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/constraints/law.hpp"

#include <memory>
#include <optional>
#include <string>

namespace refdyn::constraint_detail {

/// The built constraint with its default name and origin (the factories' last step).
template <typename T>
std::shared_ptr<T> named(std::shared_ptr<T> c, std::string name, ConstraintOrigin o) {
  c->name = std::move(name);
  c->origin = o;
  return c;
}

inline void need_axis(int axis, const char* what) {
  if (axis < 0 || axis > 2) throw Error(expected_got(what, "0 (x), 1 (y) or 2 (z)", std::to_string(axis)));
}
inline void need_vec(const Vec3& v, const std::string& what) {
  if (!v.allFinite() || v.norm() < 1e-12) throw Error(expected_got(what, "a finite non-zero vector", "zero or NaN"));
}

}  // namespace refdyn::constraint_detail
