#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_points_coincide() {
  ConstraintKind k;
  k.name = "points_coincide";
  k.doc = "two points coincide on the selected world axes (loop closure): r_A − r_B = 0";
  k.default_origin = ConstraintOrigin::Material;
  k.keys = {{"points", "[A, B]", true, "", "the two points"},
            {"axes", "list of x | y | z", false, "[x, y, z]", "the world axes (a planar loop: [x, y])"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const SpecValue& ps = a.reader.need(a.entry.fields, "points", a.entry.key);
    if (!ps.is_list() || ps.size() != 2) a.fail("points", "expected two point names [A, B]");
    std::vector<int> axes{0, 1, 2};
    if (a.has("axes")) {
      const SpecValue& ax = a.value("axes");
      if (!ax.is_list() || ax.size() == 0) a.fail("axes", "expected a list of axes such as [x, y]");
      axes.clear();
      for (size_t i = 0; i < ax.size(); ++i) axes.push_back(a.reader.axis(ax[i], a.key("axes")));
    }
    const std::string p0 = a.reader.point(ps[0], a.key("points"), a.model);
    const std::string p1 = a.reader.point(ps[1], a.key("points"), a.model);
    return points_coincide(a.model, p0, p1, axes, origin);
  };
  return k;
}

}  // namespace refdyn::kinds
