#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_point_coordinate() {
  ConstraintKind k;
  k.name = "point_coordinate";
  k.doc = "a world coordinate of point P follows a function of time: r_P,axis − f(t) = 0";
  k.keys = {{"point", "point", true, "", "the point P"},
            {"axis", "x | y | z", true, "", "the world axis"},
            {"function", "function of t", true, "", "f(t) [m]"},
            {"record", "name", false, "", "record f(t) in plan.csv under this column name"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const std::string p = a.point("point");
    const int axis = a.reader.axis(a.reader.need(a.entry.fields, "axis", a.entry.key), a.key("axis"));
    return point_coordinate(a.model, p, axis, a.function("function"), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
