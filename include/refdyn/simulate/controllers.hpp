#pragma once
/// Tracking controllers (paper section 3): time, plant state (q, q̇) and reference (q̂, q̂̇, q̂̈)
/// in, joint torques/forces τ out. The plant is the unconstrained model with its own force
/// elements and initial state:  M(q) q̈ + c(q, q̇) + g(q) = τ + Q_plant(t, q, q̇, z).
/// simulate_closed_loop (closed_loop.hpp) runs them; the scenario's controller kinds build them.

#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/model.hpp"

#include <string>
#include <vector>

namespace refdyn {

struct ReferenceSample {
  const Eigen::VectorXd& q;
  const Eigen::VectorXd& qd;
  const Eigen::VectorXd& qdd;
};

class Controller {
 public:
  virtual ~Controller() = default;
  virtual std::string name() const = 0;
  /// Number of the controller's own states xc (e.g. a PID's error integrals); they are part of
  /// the closed-loop state vector [q; q̇; z_plant; xc] and start at zero.
  virtual int num_states() const { return 0; }
  virtual std::vector<std::string> state_names() const { return {}; }
  /// τ (size nq) from time, plant state and reference. May use internal workspace.
  virtual void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
                       Eigen::VectorXd& tau) = 0;
  /// The same, when the caller has already evaluated M(q) and c(q, q̇) + g(q) of `model` at this
  /// (q, q̇) into `dynamics` (dynamics.M, dynamics.nle). A controller whose own model is that
  /// same Model object may use them instead of recomputing; the closed loop passes the plant's.
  /// The default ignores them.
  virtual void compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                     const ReferenceSample& ref, const Model& model, const Data& dynamics,
                                     Eigen::VectorXd& tau) {
    compute(t, q, qd, ref, tau);
  }
  /// True when compute_with_dynamics uses the M and c + g of `model` it is given (the closed
  /// loop then evaluates them for the plant and solves M q̈ = … by Cholesky; otherwise a plant
  /// from kAbaFrom coordinates on takes the articulated-body algorithm, recursive_dynamics.hpp).
  virtual bool reuses_dynamics(const Model& /*model*/) const { return false; }
  /// The entry point of the closed loop: as compute_with_dynamics (`dynamics` may be null:
  /// not evaluated), plus the controller's states xc and their derivatives xc_dot (written;
  /// null when the caller needs τ only). The default has no states.
  virtual void compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                  const ReferenceSample& ref, const double* xc, double* xc_dot, const Model& model,
                                  const Data* dynamics, Eigen::VectorXd& tau) {
    if (dynamics)
      compute_with_dynamics(t, q, qd, ref, model, *dynamics, tau);
    else
      compute(t, q, qd, ref, tau);
  }
  /// compute_with_state over dual numbers, for the closed loop's exact Jacobian (implicit
  /// integration): every input may carry derivatives — the plant state q, q̇ (n each), the
  /// reference q̂, q̂̇, q̂̈ (n each) and the controller's states xc; writes τ (n) and xc_dot. The
  /// controllers refdyn provides have it; the default throws an Error naming the controller.
  virtual void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                            const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                            JacobianScalar* tau, JacobianScalar* xc_dot) const;
};

/// Feedback linearization + PD, paper (3.2)–(3.4):
///   τ = M(q) u + c(q, q̇) + g(q),   u_i = q̂̈_i − 2δ_i ė_i − δ_i² e_i,   e = q − q̂.
/// With a perfect model each error obeys ë + 2δė + δ²e = 0: e(t) = (e0 + (ė0 + δe0) t) e^(−δt).
class ComputedTorquePD final : public Controller {
 public:
  /// `model` is the controller's model of the plant (kept by reference); delta: one gain per joint [1/s].
  ComputedTorquePD(const Model& model, Eigen::VectorXd delta);
  std::string name() const override { return "computed_torque_pd"; }
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
  /// Uses dynamics.M and dynamics.nle when `model` is this controller's model (same object).
  bool reuses_dynamics(const Model& model) const override { return &model == &model_; }
  void compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                             const ReferenceSample& ref, const Model& model, const Data& dynamics,
                             Eigen::VectorXd& tau) override;
  void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                    const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                    JacobianScalar* tau, JacobianScalar* xc_dot) const override;
 private:
  void outer_loop(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r);  // u_
  const Model& model_;
  Data data_;
  Eigen::VectorXd delta_, u_;
};

/// PD + gravity compensation: τ = g(q) − K_p e − K_d ė.
class PDGravity final : public Controller {
 public:
  PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd);
  std::string name() const override { return "pd_gravity"; }
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
  void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                    const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                    JacobianScalar* tau, JacobianScalar* xc_dot) const override;
 private:
  const Model& model_;
  Data data_;
  Eigen::VectorXd kp_, kd_;
};

/// PID + gravity compensation: τ = g(q) − K_p e − K_i ξ − K_d ė with ξ̇ = e (one integral
/// state per joint, in the closed-loop state vector). The integral removes the steady error
/// that a constant disturbance leaves under PD (−F/K_p).
class PIDGravity final : public Controller {
 public:
  PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd);
  std::string name() const override { return "pid_gravity"; }
  int num_states() const override { return model_.nv; }
  std::vector<std::string> state_names() const override;
  /// τ with zero integral states.
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) override;
  void compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
                          const double* xc, double* xc_dot, const Model& model, const Data* dynamics,
                          Eigen::VectorXd& tau) override;
  void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                    const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                    JacobianScalar* tau, JacobianScalar* xc_dot) const override;
 private:
  const Model& model_;
  Data data_;
  Eigen::VectorXd kp_, ki_, kd_;
};

}  // namespace refdyn
