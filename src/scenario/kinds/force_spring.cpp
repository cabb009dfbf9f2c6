#include "kinds.hpp"

namespace refdyn::kinds {

ForceKind force_spring() {
  ForceKind k;
  k.name = "spring";
  k.doc = "joint spring τ = −k (q_j − q_rest)";
  k.keys = {{"joint", "joint", true, "", "the joint"},
            {"stiffness", "number", true, "", "k"},
            {"rest", "number", false, "0", "q_rest"}};
  k.build = [](const EntryArgs& a) {
    const std::string j = a.joint("joint");
    return joint_spring(a.model, j, a.number("stiffness"), a.number_or("rest", 0.0));
  };
  return k;
}

}  // namespace refdyn::kinds
