#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_pid_gravity() {
  ControllerKind k;
  k.name = "pid_gravity";
  k.doc = "PID + gravity compensation: τ = g(q) − K_p e − K_i ξ − K_d ė, ξ̇ = e (the integrals ξ are states of "
          "the closed loop, recorded as xi_<joint>)";
  k.keys = {{"kp", "per-joint gains", true, "", "K_p"},
            {"ki", "per-joint gains", true, "", "K_i"},
            {"kd", "per-joint gains", true, "", "K_d"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Eigen::VectorXd kp = gains(a, "kp"), ki = gains(a, "ki"), kd = gains(a, "kd");
    return [kp, ki, kd](const Model& m) { return std::make_unique<PIDGravity>(m, kp, ki, kd); };
  };
  return k;
}

}  // namespace refdyn::kinds
