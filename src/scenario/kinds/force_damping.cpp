#include "kinds.hpp"

namespace refdyn::kinds {

ForceKind force_damping() {
  ForceKind k;
  k.name = "damping";
  k.doc = "viscous joint damping τ = −b q̇_j";
  k.keys = {{"joint", "joint", true, "", "the joint"}, {"coefficient", "number", true, "", "b"}};
  k.build = [](const EntryArgs& a) {
    const std::string j = a.joint("joint");
    return joint_damping(a.model, j, a.number("coefficient"));
  };
  return k;
}

}  // namespace refdyn::kinds
