#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_pid_gravity() {
  ControllerKind k;
  k.name = "pid_gravity";
  k.doc = "PID + gravity compensation: τ = g(q) − K_p e − K_i ξ − K_d ė, ξ̇ = e on the motors (the integrals ξ are "
          "states of the closed loop, recorded as xi_<joint>)";
  k.keys = {{"kp", "per-joint gains", true, "", "K_p, one per motor (actuators)"},
            {"ki", "per-joint gains", true, "", "K_i, one per motor"},
            {"kd", "per-joint gains", true, "", "K_d, one per motor"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Actuation act = actuation_of(a);
    const Eigen::VectorXd kp = gains(a, "kp", &act.actuated, "its motors"),
                          ki = gains(a, "ki", &act.actuated, "its motors"),
                          kd = gains(a, "kd", &act.actuated, "its motors");
    return [kp, ki, kd, act](const Model& m) { return std::make_unique<PIDGravity>(m, kp, ki, kd, act); };
  };
  return k;
}

}  // namespace refdyn::kinds
