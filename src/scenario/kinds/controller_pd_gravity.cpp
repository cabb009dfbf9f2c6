#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_pd_gravity() {
  ControllerKind k;
  k.name = "pd_gravity";
  k.doc = "PD + gravity compensation: τ = g(q) − K_p e − K_d ė on the motors (with material constraints, g held "
          "through them by the least-norm motor efforts)";
  k.keys = {{"kp", "per-joint gains", true, "", "K_p, one per motor (actuators)"},
            {"kd", "per-joint gains", true, "", "K_d, one per motor"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Actuation act = actuation_of(a);
    const Eigen::VectorXd kp = gains(a, "kp", &act.actuated, "its motors"),
                          kd = gains(a, "kd", &act.actuated, "its motors");
    return [kp, kd, act](const Model& m) { return std::make_unique<PDGravity>(m, kp, kd, act); };
  };
  return k;
}

}  // namespace refdyn::kinds
