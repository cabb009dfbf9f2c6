#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_point_on_sphere() {
  ConstraintKind k;
  k.name = "point_on_sphere";
  k.doc = "point P on the sphere |r_P − c|² − R² = 0";
  k.keys = {{"point", "point", true, "", "the point P"},
            {"center", "[x, y, z]", true, "", "centre c [m]"},
            {"radius", "number", true, "", "radius R [m]"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const std::string p = a.point("point");
    return point_on_surface(a.model, p, sphere(a.numbers3("center"), a.number("radius")), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
