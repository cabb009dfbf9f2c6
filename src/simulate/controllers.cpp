// Tracking controllers (controllers.hpp).
#include "refdyn/simulate/controllers.hpp"

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

}  // namespace refdyn
