#include "gains.hpp"

namespace refdyn::kinds {

ControllerKind controller_computed_torque_pd() {
  ControllerKind k;
  k.name = "computed_torque_pd";
  k.doc = "computed torque + PD (paper (3.2)–(3.4)): τ = M(q)(q̂̈ − 2δė − δ²e) + c + g; with a perfect model each "
          "error obeys ë + 2δė + δ²e = 0. With material constraints or fewer motors: on the plant's independent "
          "coordinates (the reduced dynamics), the dependent ones following from the constraints, the motor efforts "
          "the least-norm (or unique) ones that realise it";
  k.keys = {{"delta", "per-joint gains", true, "",
             "δ [1/s] (critically damped error dynamics), one per coordinate the controller assigns (every joint "
             "without material constraints; else the plant's independent coordinates)"}};
  k.build = [](const EntryArgs& a) -> ControllerFactory {
    const Actuation act = actuation_of(a);
    const std::vector<int> assigned = act.assignable();
    const Eigen::VectorXd delta = gains(a, "delta", &assigned, "the plant's independent coordinates");
    return [delta, act](const Model& m) { return std::make_unique<ComputedTorquePD>(m, delta, act); };
  };
  return k;
}

}  // namespace refdyn::kinds
