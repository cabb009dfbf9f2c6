#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_point_speed() {
  ConstraintKind k;
  k.name = "point_speed";
  k.doc = "prescribed speed of point P along a fixed world direction u: u·v_P − s(t) = 0 (first order)";
  k.keys = {{"point", "point", true, "", "the point P"},
            {"direction", "[x, y, z]", true, "", "the direction u (normalised)"},
            {"speed", "function of t", true, "", "s(t) [m/s]"},
            {"record", "name", false, "", "record s(t) in plan.csv under this column name"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const std::string p = a.point("point");
    return point_speed(a.model, p, a.vec3("direction"), a.function("speed"), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
