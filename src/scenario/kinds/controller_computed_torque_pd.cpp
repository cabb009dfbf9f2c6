#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_computed_torque_pd() {
  ControllerKind k;
  k.name = "computed_torque_pd";
  k.doc = "computed torque + PD (paper (3.2)–(3.4)): τ = M(q)(q̂̈ − 2δė − δ²e) + c + g; with a perfect model each "
          "error obeys ë + 2δė + δ²e = 0";
  k.keys = {{"delta", "per-joint gains", true, "", "δ [1/s] (critically damped error dynamics)"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Eigen::VectorXd delta = gains(a, "delta");
    return [delta](const Model& m) { return std::make_unique<ComputedTorquePD>(m, delta); };
  };
  return k;
}

}  // namespace refdyn::kinds
