// Tracking controllers (controllers.hpp).
#include "refdyn/simulate/controllers.hpp"

#include "refdyn/multibody/dual_dynamics.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

namespace refdyn {


ComputedTorquePD::ComputedTorquePD(const Model& model, Eigen::VectorXd delta)
    : model_(model), data_(model), delta_(std::move(delta)), u_(Eigen::VectorXd::Zero(model.nv)) {
  check_vector("computed-torque gains delta", delta_, model.nv, "one gain per joint [1/s]");
  for (int i = 0; i < model.nv; ++i)
    if (delta_[i] < 0)
      throw Error(expected_got("computed-torque gain delta[" + std::to_string(i) + "]", "a value >= 0", fmt(delta_[i])));
}

void ComputedTorquePD::outer_loop(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r) {
  // u = q̂̈ − 2δ ė − δ² e
  for (int i = 0; i < model_.nv; ++i) {
    const double e = q[i] - r.q[i], ed = qd[i] - r.qd[i];
    u_[i] = r.qdd[i] - 2.0 * delta_[i] * ed - delta_[i] * delta_[i] * e;
  }
}

void ComputedTorquePD::compute(double, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                               Eigen::VectorXd& tau) {
  outer_loop(q, qd, r);
  unchecked::mass_matrix_and_bias(model_, data_, q, qd);
  tau.noalias() = data_.M.lazyProduct(u_);
  tau += data_.nle;
}

void ComputedTorquePD::compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                             const ReferenceSample& r, const Model& model, const Data& dynamics,
                                             Eigen::VectorXd& tau) {
  if (&model != &model_) return compute(t, q, qd, r, tau);
  outer_loop(q, qd, r);
  tau.noalias() = dynamics.M.lazyProduct(u_);
  tau += dynamics.nle;
}

PDGravity::PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd)
    : model_(model), data_(model), kp_(std::move(kp)), kd_(std::move(kd)) {
  check_vector("PD gains kp", kp_, model.nv);
  check_vector("PD gains kd", kd_, model.nv);
}

void PDGravity::compute(double, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                        Eigen::VectorXd& tau) {
  unchecked::rnea(model_, data_, q, nullptr, nullptr, true, data_.g);
  tau = data_.g - kp_.cwiseProduct(q - r.q) - kd_.cwiseProduct(qd - r.qd);
}

PIDGravity::PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd)
    : model_(model), data_(model), kp_(std::move(kp)), ki_(std::move(ki)), kd_(std::move(kd)) {
  check_vector("PID gains kp", kp_, model.nv);
  check_vector("PID gains ki", ki_, model.nv);
  check_vector("PID gains kd", kd_, model.nv);
}

std::vector<std::string> PIDGravity::state_names() const {
  std::vector<std::string> n;
  for (const auto& j : model_.joint_name) n.push_back("xi_" + j);
  return n;
}

void PIDGravity::compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                         Eigen::VectorXd& tau) {
  unchecked::rnea(model_, data_, q, nullptr, nullptr, true, data_.g);
  tau = data_.g - kp_.cwiseProduct(q - r.q) - kd_.cwiseProduct(qd - r.qd);
}

void PIDGravity::compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                    const ReferenceSample& r, const double* xc, double* xc_dot, const Model&,
                                    const Data*, Eigen::VectorXd& tau) {
  compute(t, q, qd, r, tau);
  for (int i = 0; i < model_.nv; ++i) {
    tau[i] -= ki_[i] * xc[i];
    if (xc_dot) xc_dot[i] = q[i] - r.q[i];
  }
}

void Controller::compute_dual(double, const JacobianScalar*, const JacobianScalar*, const JacobianScalar*,
                              const JacobianScalar*, const JacobianScalar*, const JacobianScalar*, JacobianScalar*,
                              JacobianScalar*) const {
  throw Error("controller '" + name() + "' has no exact derivatives (Controller::compute_dual), which the closed "
              "loop's implicit integration needs (hint: use method: rk4 or dopri5, or implement compute_dual)");
}

// τ = M(q) u + c + g = the inverse dynamics at q̈ = u.
void ComputedTorquePD::compute_dual(double, const JacobianScalar* q, const JacobianScalar* qd,
                                    const JacobianScalar* q_ref, const JacobianScalar* qd_ref,
                                    const JacobianScalar* qdd_ref, const JacobianScalar*, JacobianScalar* tau,
                                    JacobianScalar*) const {
  const int n = model_.nv;
  thread_local std::vector<JacobianScalar> u;
  u.resize(n);
  for (int i = 0; i < n; ++i) {
    const JacobianScalar e = q[i] - q_ref[i], ed = qd[i] - qd_ref[i];
    u[i] = qdd_ref[i] - 2.0 * delta_[i] * ed - delta_[i] * delta_[i] * e;
  }
  inverse_dynamics_dual(model_, q, qd, u.data(), true, tau);
}

namespace {
// τ = g(q) − K_p e − K_d ė (PD and PID + gravity).
void pd_gravity_dual(const Model& model, const Eigen::VectorXd& kp, const Eigen::VectorXd& kd, const JacobianScalar* q,
                     const JacobianScalar* qd, const JacobianScalar* q_ref, const JacobianScalar* qd_ref,
                     JacobianScalar* tau) {
  inverse_dynamics_dual(model, q, nullptr, nullptr, true, tau);
  for (int i = 0; i < model.nv; ++i) tau[i] -= kp[i] * (q[i] - q_ref[i]) + kd[i] * (qd[i] - qd_ref[i]);
}
}  // namespace

void PDGravity::compute_dual(double, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                             const JacobianScalar* qd_ref, const JacobianScalar*, const JacobianScalar*,
                             JacobianScalar* tau, JacobianScalar*) const {
  pd_gravity_dual(model_, kp_, kd_, q, qd, q_ref, qd_ref, tau);
}

void PIDGravity::compute_dual(double, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                              const JacobianScalar* qd_ref, const JacobianScalar*, const JacobianScalar* xc,
                              JacobianScalar* tau, JacobianScalar* xc_dot) const {
  pd_gravity_dual(model_, kp_, kd_, q, qd, q_ref, qd_ref, tau);
  for (int i = 0; i < model_.nv; ++i) {
    tau[i] -= ki_[i] * xc[i];
    if (xc_dot) xc_dot[i] = q[i] - q_ref[i];
  }
}

}  // namespace refdyn
