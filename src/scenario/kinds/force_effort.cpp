#include "kinds.hpp"

namespace refdyn::kinds {

ForceKind force_effort() {
  ForceKind k;
  k.name = "effort";
  k.doc = "a prescribed joint torque or force τ = f(t), an actuator";
  k.keys = {{"joint", "joint", true, "", "the joint"}, {"value", "function of t", true, "", "f(t) [N m or N]"}};
  k.build = [](const EntryArgs& a) {
    const std::string j = a.joint("joint");
    return joint_effort(a.model, j, a.function("value"));
  };
  return k;
}

}  // namespace refdyn::kinds
