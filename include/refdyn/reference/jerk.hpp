#pragma once
/// Programmed constraints of order p = 3 (jerk), B(t, q, q̇) q⃛ + s(t, q, q̇, q̈) = 0, and the
/// reference dynamics they give (docs/higher_order.md, "Order p = 3").
///
/// Reading of the paper's GPME (2.4) for p = 3: by Tsenov's identity ∂P_p/∂q^(p) is the
/// Lagrange expression for every p ≥ 2, so the GPME are Nᵀ(M q̈ − F) = 0 with N spanning the
/// null space of B — the reactions act along Bᵀ: M q̈ = F + Bᵀλ. With the jerk row this is an
/// ODE of order 3 in q; the state is x = [q; q̇; q̈], and q⃛ solves, with R = M q̈ − F,
///     M q⃛ − Bᵀν = Ḃᵀλ − Ṙ|_{q⃛=0} − κ R,      B q⃛ = −s,
/// where λ = (B M⁻¹ Bᵀ)⁻¹ B M⁻¹ R is the reaction carried by the state (lambda() reports −λ, the
/// sign of ReferenceDynamics: Q_c = −Bᵀλ) and κ ≥ 0 a user-set
/// Baumgarte-type gain on the projected dynamics residual Nᵀ(M q̈ − F) (it obeys
/// d/dt(NᵀR) = −κ NᵀR + Ṅᵀ(R − Bᵀλ); along a consistent solution R = Bᵀλ and the equation is
/// exact). Ṙ|_{q⃛=0} = Ṁ q̈ + ċ + ġ comes from forward-mode AD (dual numbers) of a
/// scalar-templated recursive Newton–Euler, the point jerks and Ċ from the same AD of the point
/// kinematics, Ḃ from the exact Hessian of the constraint expression: no finite differences.
///
/// Scope (checked, with errors naming the constraint or element): rows of order ≤ 2 beside the
/// jerk rows are taken to the jerk level (JerkDynamics below); force elements must provide their
/// rate (ForceElement::add_rate_with_states); the jerk expression
/// is linear in the jerks jx(P), jy(P), jz(P), qddd(j), and their coefficients do not depend on
/// accelerations (ax(P)…, qdd(j)) or jerks, so that B = B(t, q, q̇).

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/multibody/model.hpp"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

/// Motion of a model point along (q, q̇, q̈): position, velocity, acceleration, the jerk at
/// q⃛ = 0 (the full jerk is j + C q⃛), the point Jacobian C and its rate Ċ (world frame).
struct PointMotion {
  Vec3 r = Vec3::Zero(), v = Vec3::Zero(), a = Vec3::Zero(), j = Vec3::Zero();
  Eigen::Matrix<double, 3, Eigen::Dynamic> C, Cdot;
};

/// PointMotion of `point` at (q, q̇, q̈): one forward recursion on dual numbers.
void point_motion(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                  const Eigen::VectorXd& qdd, int point, PointMotion& out);

/// τ = M(q) q̈ + c(q, q̇) + g(q) and its rate along the motion at q⃛ = 0,
/// τ̇ = Ṁ q̈ + ċ + ġ (the full rate is τ̇ + M q⃛): the recursive Newton–Euler algorithm
/// templated on the scalar and run on dual numbers (q + εq̇, q̇ + εq̈, q̈ + 0ε).
void inverse_dynamics_rate(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                           const Eigen::VectorXd& qdd, Eigen::VectorXd& tau, Eigen::VectorXd& tau_rate);

/// One jerk-level constraint row written as an expression (see the header comment for the
/// variables and the conditions); exact derivatives by GiNaC.
class JerkConstraint {
 public:
  /// `source_text` (optional): the acceleration-level expression `text` is the time derivative
  /// of (differentiate_expression_text); it gives a consistent initial acceleration
  /// (JerkDynamicsOptions::consistent_with, source_value).
  JerkConstraint(const Model& model, const std::string& name, const std::string& text,
                 const std::map<std::string, double>& parameters = {}, const std::string& source_text = "");
  ~JerkConstraint();
  const std::string& name() const { return name_; }
  const std::string& text() const { return text_; }
  const std::string& source_text() const { return source_text_; }
  /// The source expression's value with q̈ = 0 (its s: the point accelerations are the drifts in
  /// `points`, which must be point motions at q̈ = 0). Throws Error without a source.
  double source_value(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                      const std::vector<PointMotion>& points) const;
  const std::vector<int>& points() const { return points_; }
  /// s (value with q⃛ = 0), the row B (1×n) and its rate Ḃ along the motion, from the point
  /// motions (indexed by model point index; only this constraint's points are read).
  void evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                const std::vector<PointMotion>& points, double& s, Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> B,
                Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> Bdot) const;

 private:
  struct Impl;
  std::string name_, text_, source_text_;
  std::vector<int> points_;
  std::unique_ptr<Impl> impl_;
};
using JerkConstraintPtr = std::shared_ptr<const JerkConstraint>;

/// A jerk constraint as an entry of a ConstraintSet (what a scenario's `order: jerk` builds):
/// order() == 3, one row. Its evaluate() throws: jerk rows are evaluated by JerkDynamics, and a
/// problem with jerk rows has only jerk rows (build_problem checks it).
NewConstraint jerk_expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                         const std::map<std::string, double>& parameters = {},
                                         ConstraintOrigin origin = ConstraintOrigin::Programmed,
                                         const std::string& source_text = "");
/// A jerk row formed as the time derivative of the acceleration-level expression
/// `acceleration_text` (scenario: `order: jerk` with `differentiate: true`), keeping the source
/// for a consistent q̈0.
NewConstraint differentiated_jerk_constraint(const Model& model, const std::string& name,
                                             const std::string& acceleration_text,
                                             const std::map<std::string, double>& parameters = {},
                                             ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// The JerkConstraint behind a constraint made by jerk_expression_constraint, else null.
JerkConstraintPtr jerk_constraint_of(const Constraint& c);

struct JerkDynamicsOptions {
  double kappa = 50.0;  ///< gain on the projected dynamics residual Nᵀ(M q̈ − F) and on the rows' ψ [1/s]
  /// Baumgarte gains of the rows of order ≤ 2 (as ReferenceDynamicsOptions): ψ = Φ̈ + 2αΦ̇ + β²Φ
  /// (holonomic), ψ = ċ + β₁c (first order), ψ = B q̈ + s (acceleration).
  double alpha = 100.0, beta = 50.0, beta_first_order = 50.0;
  /// Jerk rows (by name) whose initial acceleration is made consistent with the acceleration row
  /// they were differentiated from (JerkConstraint::source_text): B q̈0 + s_acc = 0.
  std::vector<std::string> consistent_with;
};

/// The reference dynamics of a problem with rows of order 3 (jerk) and, beside them, rows of
/// order 0, 1 and 2 (docs/higher_order.md, "Mixed orders"). State x = [q; q̇; q̈; z] (z: the
/// force elements' states). With R = M q̈ − F, G the stacked coefficients of every row's highest
/// derivative (A for rows of order ≤ 2, B for jerk rows), λ = (G M⁻¹ Gᵀ)⁻¹ G M⁻¹ R, q⃛ solves
///     M q⃛ − Gᵀν = Ġᵀλ − Ṙ|_{q⃛=0} − κ R,
///     B q⃛ = −s                          (jerk rows)
///     A q⃛ = −ψ̇|_{q⃛=0} − κ ψ            (rows of order ≤ 2, ψ their stabilized acceleration level)
/// All time derivatives are exact: dual numbers through the generic multibody core, the force
/// elements (add_rate / add_rate_with_states) and the constraints (evaluate_constraints_dual with
/// a seeded time).
class JerkDynamics {
 public:
  /// Jerk rows only. `forces` (optional, kept by reference): elements without a rate are rejected
  /// with an Error naming the element.
  JerkDynamics(const Model& model, std::vector<JerkConstraintPtr> constraints, JerkDynamicsOptions options = {},
               const ForceSet* forces = nullptr);
  /// Every row of `rows` (kept by copy of its entries): jerk rows (jerk_expression_constraint)
  /// and rows of order ≤ 2 (which need evaluate_dual: every kind refdyn provides has it).
  JerkDynamics(const Model& model, const ConstraintSet& rows, JerkDynamicsOptions options = {},
               const ForceSet* forces = nullptr);
  ~JerkDynamics();
  int nq() const { return n_; }
  int num_constraints() const { return m_; }
  int num_states() const { return nz_; }  ///< the force elements' states
  int state_size() const { return 3 * n_ + nz_; }
  const Model& model() const { return model_; }
  /// The jerk rows.
  const std::vector<JerkConstraintPtr>& constraints() const { return constraints_; }
  /// Every row, in the order given (jerk rows and rows of order ≤ 2).
  const ConstraintSet& constraint_set() const { return all_; }
  const ForceSet* forces() const { return forces_; }
  const JerkDynamicsOptions& options() const { return opt_; }

  /// x0 = [q0; q̇0; q̈0; z0] with q̈0 consistent with the dynamics and with every row of order ≤ 2
  /// at the acceleration level: q̈0 = M⁻¹(F + Gᵀλ0), ψ(q̈0) = 0 for the rows of order ≤ 2
  /// (with Φ = Φ̇ = 0 at q0, q̇0: Φ̈ = 0), and for each jerk row: B q̈0 + s_acc = 0 if it is in
  /// options().consistent_with, else B q̈0 = B q̈_hint with qdd_hint, else its λ0 = 0.
  /// z0: zero or `z0` (size num_states()).
  Eigen::VectorXd initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                const Eigen::VectorXd* qdd_hint = nullptr, const Eigen::VectorXd* z0 = nullptr);

  /// ẋ = [q̇; q̈; q⃛; ż]. Throws NumericalFailure when G M⁻¹ Gᵀ is singular.
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);

  // ---- results of the last derivative() call ----
  const Eigen::VectorXd& qddd() const { return qddd_; }
  /// The multipliers, with ReferenceDynamics' sign: M q̈ − F = −Gᵀλ (+ the residual ρ).
  const Eigen::VectorXd& lambda() const { return lambda_; }
  const Eigen::VectorXd& constraint_force() const { return R_; }    ///< R = M q̈ − F
  /// G: every row's coefficient of its highest derivative (m × n), in the order of constraint_set().
  const Eigen::MatrixXd& B() const { return B_; }
  /// Jerk rows: s; rows of order ≤ 2: ψ̇|_{q⃛=0} + κψ (the right-hand side is its negative).
  const Eigen::VectorXd& s() const { return s_; }
  /// Per row: jerk rows B q⃛ + s after the solve (rounding level); rows of order ≤ 2: Φ
  /// (holonomic), c (first order) or B q̈ + s (acceleration).
  const Eigen::VectorXd& row_residual() const { return row_res_; }
  /// Per row: jerk rows as row_residual(); holonomic rows Φ̇; first-order rows c; acceleration
  /// rows B q̈ + s.
  const Eigen::VectorXd& row_rate_residual() const { return row_rate_; }
  /// ‖R − Gᵀλ‖∞: the dynamics residual the gain κ keeps at integration-error level.
  double dynamics_residual() const { return dyn_res_; }
  /// The force elements' state rates ż (size num_states()).
  const Eigen::VectorXd& zdot() const { return zdot_; }

 private:
  void setup();
  void forces_and_rates(double t, const double* z);  // Q_, zdot_, Qdot_ at q_, qd_, qdd_
  void evaluate_rows(double t);                      // B_, Bdot_, s_, rows' residuals at q_, qd_, qdd_
  const Model& model_;
  const ForceSet* forces_;
  ConstraintSet all_, lower_;
  std::vector<int> lower_row_, jerk_row_;  // global row of each lower / jerk row
  std::vector<char> lower_order_;          // 0, 1, 2 per lower row
  std::vector<JerkConstraintPtr> constraints_;
  JerkDynamicsOptions opt_;
  int n_, m_, nz_ = 0;
  Data data_;
  std::vector<int> points_;
  std::vector<PointMotion> motion_;
  struct DualRows;
  std::unique_ptr<DualRows> dual_;
  Eigen::VectorXd q_, qd_, qdd_, tau_, taud_, R_, lambda_, qddd_, s_, row_res_, row_rate_, Q_, Qdot_, zdot_, psi_;
  Eigen::MatrixXd B_, Bdot_;
  double dyn_res_ = 0;
};

}  // namespace refdyn
