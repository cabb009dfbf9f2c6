#pragma once
/// The machine as it is built, as the controllers see it (docs/scenario.md, "The plant"): its
/// model, its material constraints (loop closures, rolling without slip, gear couplings: the
/// rows with origin: material; programmed rows never enter the plant), the joints that have a
/// motor, and the coordinates the controllers assign (the independent coordinates of the
/// material rows).
///
/// With material rows A q̈ = rhs (the plant's stabilised rows: Baumgarte
/// rhs = −γ − 2αΦ̇ − β²Φ, first order −γ − β₁c) and the partition q = (q_ind, q_dep),
///     q̈_dep = K_dc⁻¹ (rhs − K_ic q̈_ind),   N = ∂q̇/∂q̇_ind = [I; −K_dc⁻¹K_ic]  (n × k),
/// a desired q̈_ind = u fixes q̈* and the generalized force b = M q̈* + c + g it needs. Motors act
/// through the selection S (n × n_a, a unit column per actuated joint); the reactions Aᵀλ do no
/// work along N, so the motor efforts τ_a realise q̈* exactly when
///     Nᵀ S τ_a = Nᵀ b                       (k equations, n_a unknowns)
/// — the unique solution when n_a = k, the least-norm one τ_a = Pᵀ(PPᵀ)⁻¹Nᵀb (P = NᵀS) when
/// n_a > k; n_a < k or a rank-deficient P: motors that cannot realise it (an error at load,
/// naming the coordinates no motor reaches). Without material rows and with every joint a
/// motor (the paper's manipulator), N = S = I and τ = b: the unconstrained computed torque.
#include "refdyn/common/dual_eigen.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/model.hpp"

#include <memory>
#include <string>
#include <vector>

namespace refdyn {

struct Actuation {
  /// The plant's material rows (holonomic and first order); null or empty: none.
  std::shared_ptr<const ConstraintSet> material;
  std::vector<int> actuated;     ///< joints with a motor, ascending
  std::vector<int> independent;  ///< coordinates the controllers assign, ascending (all without material rows)
  std::vector<int> dependent;    ///< the others, ascending
  double alpha = 0, beta = 0, beta_first_order = 0;  ///< the plant's stabilisation (0 under projection)
  /// The independent coordinates were chosen by conditioning (the motors do not form a partition):
  /// along the run the controllers then assign the best-conditioned set wherever the initial
  /// one's κ(K_dc) exceeds kSwitchCondition (a nonholonomic row's partition can degenerate as
  /// the mechanism moves: the unicycle turning through 90°), so gains are needed on every
  /// coordinate that can be assigned (assignable()).
  bool switching = false;
  static constexpr double kSwitchCondition = 10.0;
  /// The coordinates a controller may assign: the independent ones, or every joint when switching.
  std::vector<int> assignable() const;

  /// Every joint a motor and no material rows: the controllers' unconstrained laws.
  static Actuation full(const Model& model);
  bool constrained() const { return material && material->rows() > 0; }
  bool fully_actuated(const Model& model) const { return static_cast<int>(actuated.size()) == model.nv; }
  /// No material rows and every joint a motor (the laws reduce to the unconstrained ones).
  bool trivial(const Model& model) const { return !constrained() && fully_actuated(model); }
  bool is_actuated(int joint) const;
  bool is_independent(int joint) const;
  /// "a, b, c" (joint names of the list).
  static std::string names(const Model& model, const std::vector<int>& joints);
};

/// The constrained plant's evaluation at a state (t, q, q̇), for a controller on the same model:
/// its material rows (Φ, Φ̇, A, γ of Actuation::material) and, when the plant factored its
/// partition there (ReferenceDynamics::partition_factored), K_dc⁻¹ (m × m) and G = −K_dc⁻¹ K_ic
/// (m × k) for its independent and dependent coordinates (null: not factored).
struct PlantRows {
  const ConstraintEval* rows = nullptr;
  const std::vector<int>* independent = nullptr;
  const std::vector<int>* dependent = nullptr;
  const Eigen::MatrixXd* Kinv = nullptr;
  const Eigen::MatrixXd* G = nullptr;
};

/// The plant's partition and the actuation check at a state (t, q, q̇) that satisfies the
/// material rows: the independent coordinates are the actuated joints when there are exactly k =
/// n − m of them and they form a partition with cond(K_dc) ≤ max_condition, else the
/// best-conditioned set (ReferenceDynamics::choose_partition); then P = NᵀS must have rank k.
/// Throws Error (to be located by the caller at `actuators`) when the motors cannot realise the
/// assigned accelerations: fewer motors than k, or coordinates no motor reaches (named).
Actuation make_actuation(const Model& model, std::shared_ptr<const ConstraintSet> material, std::vector<int> actuated,
                         double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double alpha, double beta,
                         double beta_first_order, double max_condition);

/// The controllers' model of the plant over a scalar S (double, or JacobianScalar for the closed
/// loop's exact Jacobian): one workspace per controller (not shared between threads).
template <class S>
class ActuatedModel {
 public:
  using Vector = ad::VectorX<S>;
  using Matrix = ad::MatrixX<S>;
  ActuatedModel(const Model& model, const Actuation& actuation);
  /// Evaluates the material rows at (t, q, q̇) (A, rhs, K_dc, N): needed before accelerations and
  /// efforts when the plant is constrained. `plant` (S = double only; may be null): the rows
  /// already evaluated at this (t, q, q̇) for this model (the constrained plant's), used instead,
  /// and the plant's factored partition when it is the one assigned here. Returns false when
  /// K_dc is singular.
  bool set_state(double t, const S* q, const S* qd, const PlantRows* plant = nullptr);
  /// q̈* from the assigned accelerations u (one per independent coordinate, in Actuation::independent order).
  void accelerations(const Vector& u, Vector& qdd) const;
  /// Motor efforts realising the generalized force b (n): tau (n) gets S τ_a (0 at joints
  /// without a motor). Returns false when NᵀS is singular here (the motors cannot realise it).
  bool efforts(const Vector& b, Vector& tau) const;
  /// M(q) q̈ + c(q, q̇) + g(q) (q̇ null: zero velocity; q̈ null: zero) into out (n). S = double,
  /// q̇ and q̈ given: from `dynamics` (M and c + g at this state) when given, else RNEA.
  void inverse_dynamics(const S* q, const S* qd, const S* qdd, S* out, const Data* dynamics = nullptr);
  /// The unconstrained, fully actuated computed torque τ = M(q) u + c(q, q̇) + g(q) (n values
  /// of u). S = double: from `dynamics` (M and c + g at this state) when given, else CRBA + RNEA.
  void computed_torque(const S* q, const S* qd, const Vector& u, const Data* dynamics, S* tau);
  /// g(q) into a workspace vector (valid until the next call).
  const Vector& gravity(const S* q);
  /// Workspace vectors for the laws (no allocation after the first call with a size).
  Vector& scratch(int which, int size) {
    Vector& v = scratch_[which];
    if (v.size() != size) v.resize(size);
    return v;
  }
  const Model& model() const { return model_; }
  const Actuation& actuation() const { return act_; }
  /// The coordinates assigned at the last set_state (Actuation::independent unless switching).
  const std::vector<int>& independent() const { return ind_; }

 private:
  void choose_partition();  // ind_, dep_ from A's values (Actuation::switching)
  bool factor(const Matrix& A);  // N_d and q̈_p from A and the workspace's rhs
  const Model& model_;
  const Actuation& act_;
  struct Workspace;
  std::shared_ptr<Workspace> ws_;
  Matrix Nd_;     // −K_dc⁻¹ K_ic (m × k): the dependent rows of N
  Vector qdd_p_;  // K_dc⁻¹ rhs (m): the dependent part of q̈ for u = 0
  Vector g_;
  Vector scratch_[4];
  std::vector<int> ind_, dep_;
};

// Instantiated for double and JacobianScalar in src/simulate/actuation.cpp, where the members are
// defined. No `extern template` here: it would instantiate the class (its Eigen members over dual
// numbers) in every file that includes this header, ~5 CPU-seconds each (docs/testing.md, "CI time").

}  // namespace refdyn
