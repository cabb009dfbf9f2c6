#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_joint_trajectory() {
  ConstraintKind k;
  k.name = "joint_trajectory";
  k.doc = "prescribed joint motion q_j − f(t) = 0";
  k.keys = {{"joint", "joint", true, "", "the joint j"},
            {"function", "function of t", true, "", "f(t) [rad or m]"},
            {"record", "name", false, "", "record f(t) in plan.csv under this column name"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    return joint_trajectory(a.model, a.joint("joint"), a.function("function"), origin);
  };
  return k;
}

}  // namespace refdyn::kinds
