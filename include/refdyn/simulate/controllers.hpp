#pragma once
/// Tracking controllers (paper section 3): time, plant state (q, q̇), reference (q̂, q̂̇, q̂̈) and the
/// controller's own states in, motor efforts τ out (0 at joints without a motor).
///
/// Each controller is one law written once over a scalar S (ControllerLaw below): S = double
/// for the simulation, S = JacobianScalar (dual numbers) for the closed loop's exact Jacobian
/// under implicit integration. The law sees the plant through ActuatedModel<S> (actuation.hpp):
/// its material constraints, its motors and the coordinates it assigns. Without material rows
/// and with a motor at every joint (the paper's manipulator) the laws are the textbook ones
/// below; otherwise they act on the reduced dynamics (docs/scenario.md, "The plant").
///
/// simulate_closed_loop (closed_loop.hpp) runs them; the scenario's controller kinds build them.

#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/simulate/actuation.hpp"

#include <string>
#include <vector>

namespace refdyn {

struct ReferenceSample {
  const Eigen::VectorXd& q;
  const Eigen::VectorXd& qd;
  const Eigen::VectorXd& qdd;
};

/// What a law reads, over its scalar: q, q̇ (n each), the reference q̂, q̂̇, q̂̈ (n each) and the
/// controller's states xc (null: zero). `dynamics` (S = double only; may be null): the plant's
/// M and c + g at this (q, q̇), computed by the closed loop for the same Model object. `material`
/// (S = double only; may be null): the constrained plant's evaluation at this (t, q, q̇) for the
/// same Model object (its material rows, and its partition's factorization: PlantRows).
template <class S>
struct ControlInput {
  double t;
  const S* q;
  const S* qd;
  const S* q_ref;
  const S* qd_ref;
  const S* qdd_ref;
  const S* xc;
  const Data* dynamics = nullptr;
  const PlantRows* material = nullptr;
};

class Controller {
 public:
  virtual ~Controller() = default;
  virtual std::string name() const = 0;
  /// Number of the controller's own states xc (e.g. a PID's error integrals); they are part of
  /// the closed-loop state vector [q; q̇; z_plant; xc] and start at zero.
  virtual int num_states() const { return 0; }
  virtual std::vector<std::string> state_names() const { return {}; }
  /// τ (size n) and, when xc_dot is not null, the states' derivatives. xc null: states at zero.
  /// `model`, `dynamics` (optional): M and c + g of `model` already evaluated at this (q, q̇)
  /// (dynamics->M, dynamics->nle); a controller whose own model is that same object may use them.
  /// `material` (optional): the constrained plant's evaluation for `model` at this (t, q, q̇) —
  /// the rows of actuation().material and the plant's factored partition (PlantRows) — reused
  /// on the same conditions.
  virtual void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
                       const double* xc, double* xc_dot, Eigen::VectorXd& tau, const Model* model = nullptr,
                       const Data* dynamics = nullptr, const PlantRows* material = nullptr) = 0;
  /// τ with the states at zero.
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               Eigen::VectorXd& tau) {
    compute(t, q, qd, ref, nullptr, nullptr, tau);
  }
  /// True when compute uses the M and c + g of `model` it is given (the closed loop then
  /// evaluates them for the plant and solves M q̈ = … by Cholesky; otherwise a plant from
  /// kAbaFrom coordinates on takes the articulated-body algorithm, recursive_dynamics.hpp).
  virtual bool reuses_dynamics(const Model& /*model*/) const { return false; }
  /// The same law over dual numbers, for the closed loop's exact Jacobian (implicit
  /// integration): every input may carry derivatives; writes τ (n) and xc_dot (when not null).
  virtual void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                            const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                            JacobianScalar* tau, JacobianScalar* xc_dot) const = 0;
  /// The plant as this controller sees it (motors, material rows, assigned coordinates).
  virtual const Actuation& actuation() const = 0;
};

/// A controller written once: Derived provides
///     template <class S> void law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* xc_dot);
/// and this class instantiates it for double (compute) and for dual numbers (compute_dual).
/// Failures inside a law (the motors cannot realise the assigned accelerations at this state)
/// throw NumericalFailure with the time.
template <class Derived>
class ControllerLaw : public Controller {
 public:
  ControllerLaw(const Model& model, Actuation actuation)
      : model_(model), actuation_(std::move(actuation)), plant_(model, actuation_), plant_dual_(model, actuation_) {}
  ControllerLaw(const ControllerLaw&) = delete;  // plant_ refers to actuation_
  ControllerLaw& operator=(const ControllerLaw&) = delete;
  using Controller::compute;  // τ with the states at zero
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               const double* xc, double* xc_dot, Eigen::VectorXd& tau, const Model* model = nullptr,
               const Data* dynamics = nullptr, const PlantRows* material = nullptr) override {
    tau.resize(model_.nv);
    const bool same = model == &model_;
    const ControlInput<double> in{t, q.data(), qd.data(), ref.q.data(), ref.qd.data(), ref.qdd.data(), xc,
                                  same ? dynamics : nullptr, same ? material : nullptr};
    static_cast<Derived*>(this)->law(in, plant_, tau.data(), xc_dot);
  }
  void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                    const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                    JacobianScalar* tau, JacobianScalar* xc_dot) const override {
    const ControlInput<JacobianScalar> in{t, q, qd, q_ref, qd_ref, qdd_ref, xc, nullptr, nullptr};
    auto* self = const_cast<Derived*>(static_cast<const Derived*>(this));  // workspaces only
    self->law(in, self->plant_dual_, tau, xc_dot);
  }
  const Actuation& actuation() const override { return actuation_; }
  const Model& model() const { return model_; }

 protected:
  const Model& model_;
  Actuation actuation_;
  ActuatedModel<double> plant_;
  ActuatedModel<JacobianScalar> plant_dual_;
};

/// Feedback linearization + PD, paper (3.2)–(3.4), on the coordinates it assigns
/// (Actuation::independent; every joint without material rows):
///   u_i = q̂̈_i − 2δ_i ė_i − δ_i² e_i,  e = q − q̂,
///   q̈* from u and the material rows, τ = the motor efforts realising M q̈* + c + g.
/// With a perfect model each assigned error obeys ë + 2δė + δ²e = 0: e(t) = (e0 + (ė0 + δe0) t) e^(−δt).
/// Unconstrained, every joint a motor: τ = M(q) u + c(q, q̇) + g(q).
class ComputedTorquePD final : public ControllerLaw<ComputedTorquePD> {
 public:
  /// `model` is the controller's model of the plant (kept by reference); delta: one gain per
  /// joint [1/s] (only the assigned coordinates' gains are used).
  ComputedTorquePD(const Model& model, Eigen::VectorXd delta, Actuation actuation);
  ComputedTorquePD(const Model& model, Eigen::VectorXd delta) : ComputedTorquePD(model, delta, Actuation::full(model)) {}
  std::string name() const override { return "computed_torque_pd"; }
  /// Uses the given M and c + g when `model` is this controller's model (same object) and the
  /// plant is unconstrained and fully actuated.
  bool reuses_dynamics(const Model& model) const override {
    return &model == &model_ && actuation_.trivial(model_);
  }
  template <class S>
  void law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* xc_dot);

 private:
  Eigen::VectorXd delta_, u_;
};

/// PD + gravity compensation on the motors: τ = S τ_g − K_p e − K_d ė, with τ_g the motor
/// efforts that hold g(q) through the material rows (τ_g = g without them) and the gains on the
/// actuated joints.
class PDGravity final : public ControllerLaw<PDGravity> {
 public:
  PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd, Actuation actuation);
  PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd)
      : PDGravity(model, std::move(kp), std::move(kd), Actuation::full(model)) {}
  std::string name() const override { return "pd_gravity"; }
  template <class S>
  void law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* xc_dot);

 private:
  Eigen::VectorXd kp_, kd_;
};

/// PID + gravity compensation: PDGravity − K_i ξ with ξ̇ = e (one integral state per actuated
/// joint, in the closed-loop state vector). The integral removes the steady error that a
/// constant disturbance leaves under PD (−F/K_p).
class PIDGravity final : public ControllerLaw<PIDGravity> {
 public:
  PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd, Actuation actuation);
  PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd)
      : PIDGravity(model, std::move(kp), std::move(ki), std::move(kd), Actuation::full(model)) {}
  std::string name() const override { return "pid_gravity"; }
  int num_states() const override { return static_cast<int>(actuation_.actuated.size()); }
  std::vector<std::string> state_names() const override;
  template <class S>
  void law(const ControlInput<S>& in, ActuatedModel<S>& plant, S* tau, S* xc_dot);

 private:
  Eigen::VectorXd kp_, ki_, kd_;
};

}  // namespace refdyn
