#include "kinds.hpp"

namespace refdyn::kinds {

ForceKind force_flexible_drive() {
  ForceKind k;
  k.name = "flexible_drive";
  k.doc = "flexible drive τ = s (ψ_dr(t) − q_j) + d (ψ̇_dr(t) − q̇_j), an actuator; records psi_dr and tau_drive "
          "(suffixed _<name> when the element has a name; without one, _<joint> when another element of the list "
          "records the same names)";
  k.keys = {{"joint", "joint", true, "", "the driven joint"},
            {"stiffness", "number", true, "", "s [N m/rad or N/m]"},
            {"damping", "number", true, "", "d [N m s/rad or N s/m]"},
            {"profile", "function of t", true, "", "the drive displacement ψ_dr(t)"}};
  k.build = [](const EntryArgs& a) -> NewForceElement {
    const std::string j = a.joint("joint");
    const FlexibleDriveParams p{a.number("stiffness"), a.number("damping")};
    return std::make_shared<FlexibleDrive>(a.model, j, p, a.function("profile"));
  };
  return k;
}

}  // namespace refdyn::kinds
