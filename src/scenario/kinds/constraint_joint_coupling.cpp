#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_joint_coupling() {
  ConstraintKind k;
  k.name = "joint_coupling";
  k.doc = "two joints coupled linearly (a gear pair, a belt, a URDF mimic): q_joint − ratio·q_leader − offset = 0";
  k.default_origin = ConstraintOrigin::Material;
  k.keys = {{"joint", "joint", true, "", "the driven joint"},
            {"leader", "joint", true, "", "the leading joint"},
            {"ratio", "number", true, "", "the ratio"},
            {"offset", "number", false, "0", "the offset [rad or m]"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    const std::string j = a.joint("joint"), l = a.joint("leader");
    return joint_coupling(a.model, j, l, a.number("ratio"), a.number_or("offset", 0.0), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
