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
/// Scope (checked, with errors naming the constraint or element): only expression constraints of
/// order 3, no other constraint rows in the same system, force elements only if they provide
/// their rate (ForceElement::add_rate) and have no states; the expression
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
  JerkConstraint(const Model& model, const std::string& name, const std::string& text,
                 const std::map<std::string, double>& parameters = {});
  ~JerkConstraint();
  const std::string& name() const { return name_; }
  const std::string& text() const { return text_; }
  const std::vector<int>& points() const { return points_; }
  /// s (value with q⃛ = 0), the row B (1×n) and its rate Ḃ along the motion, from the point
  /// motions (indexed by model point index; only this constraint's points are read).
  void evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                const std::vector<PointMotion>& points, double& s, Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> B,
                Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> Bdot) const;

 private:
  struct Impl;
  std::string name_, text_;
  std::vector<int> points_;
  std::unique_ptr<Impl> impl_;
};
using JerkConstraintPtr = std::shared_ptr<const JerkConstraint>;

/// A jerk constraint as an entry of a ConstraintSet (what a scenario's `order: jerk` builds):
/// order() == 3, one row. Its evaluate() throws: jerk rows are evaluated by JerkDynamics, and a
/// problem with jerk rows has only jerk rows (build_problem checks it).
NewConstraint jerk_expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                         const std::map<std::string, double>& parameters = {},
                                         ConstraintOrigin origin = ConstraintOrigin::Programmed);
/// The JerkConstraint behind a constraint made by jerk_expression_constraint, else null.
JerkConstraintPtr jerk_constraint_of(const Constraint& c);

struct JerkDynamicsOptions {
  double kappa = 50.0;  ///< gain on the projected dynamics residual Nᵀ(M q̈ − F) [1/s]
};

class JerkDynamics {
 public:
  /// `forces` (optional, kept by reference): elements with states or without add_rate() are
  /// rejected with an Error naming the element.
  JerkDynamics(const Model& model, std::vector<JerkConstraintPtr> constraints, JerkDynamicsOptions options = {},
               const ForceSet* forces = nullptr);
  int nq() const { return n_; }
  int num_constraints() const { return m_; }
  int state_size() const { return 3 * n_; }
  const Model& model() const { return model_; }
  const std::vector<JerkConstraintPtr>& constraints() const { return constraints_; }
  const ForceSet* forces() const { return forces_; }
  const JerkDynamicsOptions& options() const { return opt_; }

  /// x0 = [q0; q̇0; q̈0] with q̈0 consistent with the dynamics, Nᵀ(M q̈0 − F) = 0:
  /// q̈0 = M⁻¹(F + Bᵀλ0). Without qdd_hint λ0 = 0 (q̈0 is the free acceleration); with it,
  /// λ0 makes B q̈0 = B q̈_hint (the constrained components are the hint's).
  Eigen::VectorXd initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                const Eigen::VectorXd* qdd_hint = nullptr);

  /// ẋ = [q̇; q̈; q⃛]. Throws NumericalFailure when B M⁻¹ Bᵀ is singular.
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot);

  // ---- results of the last derivative() call ----
  const Eigen::VectorXd& qddd() const { return qddd_; }
  /// The multipliers, with ReferenceDynamics' sign: M q̈ − F = −Bᵀλ (+ the residual ρ).
  const Eigen::VectorXd& lambda() const { return lambda_; }
  const Eigen::VectorXd& constraint_force() const { return R_; }    ///< R = M q̈ − F
  const Eigen::MatrixXd& B() const { return B_; }
  const Eigen::VectorXd& s() const { return s_; }
  /// Per row: B q⃛ + s after the solve (rounding level).
  const Eigen::VectorXd& row_residual() const { return row_res_; }
  /// ‖R − Bᵀλ‖∞: the dynamics residual the gain κ keeps at integration-error level.
  double dynamics_residual() const { return dyn_res_; }

 private:
  void forces_and_rates(double t);  // Q_, Qdot_ at q_, qd_, qdd_
  const Model& model_;
  const ForceSet* forces_;
  std::vector<JerkConstraintPtr> constraints_;
  JerkDynamicsOptions opt_;
  int n_, m_;
  Data data_;
  std::vector<int> points_;
  std::vector<PointMotion> motion_;
  Eigen::VectorXd q_, qd_, qdd_, tau_, taud_, R_, lambda_, qddd_, s_, row_res_, Q_, Qdot_;
  Eigen::MatrixXd B_, Bdot_;
  double dyn_res_ = 0;
};

}  // namespace refdyn
