// Tracking controllers (controllers.hpp): each law once, over the scalar S.
#include "refdyn/simulate/controllers.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

namespace refdyn {

namespace {

void check_gains(const char* what, const Eigen::VectorXd& g, const Model& model, const char* hint = nullptr) {
  if (hint)
    check_vector(what, g, model.nv, hint);
  else
    check_vector(what, g, model.nv);
}

[[noreturn]] void cannot_realise(double t, const Actuation& a, const Model& m, const char* what) {
  throw NumericalFailure(t, "at t = " + fmt(t) + " s the motors (" + Actuation::names(m, a.actuated) +
                                ") cannot realise the " + what + " through the material constraints (K_dc or NᵀS "
                                "singular here: a singular configuration of the mechanism)");
}

// The law's inputs as Eigen maps over S.
template <class S>
using CMap = Eigen::Map<const ad::VectorX<S>>;

}  // namespace

ComputedTorquePD::ComputedTorquePD(const Model& model, Eigen::VectorXd delta, Actuation actuation)
    : ControllerLaw(model, std::move(actuation)), delta_(std::move(delta)) {
  check_gains("computed-torque gains delta", delta_, model, "one gain per joint [1/s]");
  for (int i = 0; i < model.nv; ++i)
    if (delta_[i] < 0)
      throw Error(expected_got("computed-torque gain delta[" + std::to_string(i) + "]", "a value >= 0", fmt(delta_[i])));
  u_.resize(static_cast<Eigen::Index>(actuation_.independent.size()));
}

template <class S>
void ComputedTorquePD::law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* /*xc_dot*/) {
  // u = q̂̈ − 2δ ė − δ² e on the assigned coordinates (chosen by set_state when they switch)
  const bool trivial = actuation_.trivial(model_);
  if (!trivial && !plant.set_state(in.t, in.q, in.qd, in.material)) cannot_realise(in.t, actuation_, model_, "assigned accelerations");
  const std::vector<int>& ind = plant.independent();
  const int k = static_cast<int>(ind.size());
  ad::VectorX<S>& u = plant.scratch(0, k);
  for (int i = 0; i < k; ++i) {
    const int j = ind[i];
    const S e = in.q[j] - in.q_ref[j], ed = in.qd[j] - in.qd_ref[j];
    u[i] = in.qdd_ref[j] - 2.0 * delta_[j] * ed - delta_[j] * delta_[j] * e;
  }
  if (trivial) return plant.computed_torque(in.q, in.qd, u, in.dynamics, tau);
  // q̈* from u and the material rows, then the motor efforts that realise M q̈* + c + g.
  const int n = model_.nv;
  ad::VectorX<S>& qdd = plant.scratch(1, n);
  ad::VectorX<S>& b = plant.scratch(2, n);
  ad::VectorX<S>& t = plant.scratch(3, n);
  plant.accelerations(u, qdd);
  plant.inverse_dynamics(in.q, in.qd, qdd.data(), b.data(), in.dynamics);
  if (!plant.efforts(b, t)) cannot_realise(in.t, actuation_, model_, "assigned accelerations");
  Eigen::Map<ad::VectorX<S>>(tau, n) = t;
}

PDGravity::PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd, Actuation actuation)
    : ControllerLaw(model, std::move(actuation)), kp_(std::move(kp)), kd_(std::move(kd)) {
  check_gains("PD gains kp", kp_, model);
  check_gains("PD gains kd", kd_, model);
}

namespace {
// τ = S τ_g − K_p e − K_d ė on the motors, τ_g holding g(q) through the material rows (PD and PID).
template <class S>
void pd_gravity(const Model& model, const Actuation& a, const ControlInput<S>& in,
                ActuatedModel<S>& plant, const Eigen::VectorXd& kp, const Eigen::VectorXd& kd, S* tau) {
  const int n = model.nv;
  if (a.trivial(model)) {
    const ad::VectorX<S>& g = plant.gravity(in.q);
    Eigen::Map<ad::VectorX<S>>(tau, n) = g - kp.cwiseProduct(CMap<S>(in.q, n) - CMap<S>(in.q_ref, n)) -
                                         kd.cwiseProduct(CMap<S>(in.qd, n) - CMap<S>(in.qd_ref, n));
    return;
  }
  if (!plant.set_state(in.t, in.q, in.qd, in.material)) cannot_realise(in.t, a, model, "gravity compensation");
  ad::VectorX<S>& g = plant.scratch(2, n);
  ad::VectorX<S>& t = plant.scratch(3, n);
  plant.inverse_dynamics(in.q, nullptr, nullptr, g.data());
  if (!plant.efforts(g, t)) cannot_realise(in.t, a, model, "gravity compensation");
  for (int j = 0; j < n; ++j) tau[j] = S(0.0);
  for (int j : a.actuated) tau[j] = t[j] - kp[j] * (in.q[j] - in.q_ref[j]) - kd[j] * (in.qd[j] - in.qd_ref[j]);
}
}  // namespace

template <class S>
void PDGravity::law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* /*xc_dot*/) {
  pd_gravity(model_, actuation_, in, plant, kp_, kd_, tau);
}

PIDGravity::PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd,
                       Actuation actuation)
    : ControllerLaw(model, std::move(actuation)), kp_(std::move(kp)), ki_(std::move(ki)), kd_(std::move(kd)) {
  check_gains("PID gains kp", kp_, model);
  check_gains("PID gains ki", ki_, model);
  check_gains("PID gains kd", kd_, model);
}

std::vector<std::string> PIDGravity::state_names() const {
  std::vector<std::string> n;
  for (int j : actuation_.actuated) n.push_back("xi_" + model_.joint_name[j]);
  return n;
}

template <class S>
void PIDGravity::law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* xc_dot) {
  pd_gravity(model_, actuation_, in, plant, kp_, kd_, tau);
  const std::vector<int>& act = actuation_.actuated;
  for (size_t i = 0; i < act.size(); ++i) {
    const int j = act[i];
    if (in.xc) tau[j] -= ki_[j] * in.xc[i];
    if (xc_dot) xc_dot[i] = in.q[j] - in.q_ref[j];
  }
}

#define REFDYN_CONTROLLER_LAW(C)                                                                              \
  template void C::law<double>(const ControlInput<double>&, ActuatedModel<double>&, double*, double*);       \
  template void C::law<JacobianScalar>(const ControlInput<JacobianScalar>&, ActuatedModel<JacobianScalar>&, \
                                       JacobianScalar*, JacobianScalar*);
REFDYN_CONTROLLER_LAW(ComputedTorquePD)
REFDYN_CONTROLLER_LAW(PDGravity)
REFDYN_CONTROLLER_LAW(PIDGravity)
#undef REFDYN_CONTROLLER_LAW

}  // namespace refdyn
