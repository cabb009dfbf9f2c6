#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_pd_gravity() {
  ControllerKind k;
  k.name = "pd_gravity";
  k.doc = "PD + gravity compensation: τ = g(q) − K_p e − K_d ė";
  k.keys = {{"kp", "per-joint gains", true, "", "K_p"}, {"kd", "per-joint gains", true, "", "K_d"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Eigen::VectorXd kp = gains(a, "kp"), kd = gains(a, "kd");
    return [kp, kd](const Model& m) { return std::make_unique<PDGravity>(m, kp, kd); };
  };
  return k;
}

}  // namespace refdyn::kinds
