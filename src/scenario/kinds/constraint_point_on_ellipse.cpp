#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_point_on_ellipse() {
  ConstraintKind k;
  k.name = "point_on_ellipse";
  k.doc = "point P on the elliptic cylinder ((x − cx)/a)² + ((y − cy)/b)² − 1 = 0 about the z axis";
  k.keys = {{"point", "point", true, "", "the point P"},
            {"a", "number", true, "", "half-axis along x [m]"},
            {"b", "number", true, "", "half-axis along y [m]"},
            {"center", "[cx, cy]", false, "[0, 0]", "centre [m]"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    Number cx = 0.0, cy = 0.0;
    if (a.has("center")) {
      const SpecValue& c = a.value("center");
      if (!c.is_list() || c.size() != 2) a.fail("center", "expected [cx, cy]");
      cx = a.reader.quantity(c[0], a.key("center") + "[0]").number();
      cy = a.reader.quantity(c[1], a.key("center") + "[1]").number();
    }
    const std::string p = a.point("point");
    return point_on_surface(a.model, p, elliptic_cylinder(a.number("a"), a.number("b"), cx, cy), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
