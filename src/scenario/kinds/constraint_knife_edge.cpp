#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_knife_edge() {
  ConstraintKind k;
  k.name = "knife_edge";
  k.doc = "no lateral slip of a wheel or knife edge at P: (R a)·v_P = 0 (nonholonomic, first order)";
  k.default_origin = ConstraintOrigin::Material;
  k.keys = {{"point", "point", true, "", "the contact point P"},
            {"lateral_axis", "[x, y, z]", true, "", "the lateral axis a in the point's link frame"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const std::string p = a.point("point");
    return knife_edge(a.model, p, a.vec3("lateral_axis"), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
