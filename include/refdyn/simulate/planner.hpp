#pragma once
/// The planner interface: what plans a reference motion and feeds it to the closed loops,
/// whatever the order of the programmed constraints. Two implementations:
///   ReferencePlanner — ReferenceDynamics (rows of order ≤ 2, state [q; q̇; z]), plan_motion;
///   JerkPlanner      — JerkDynamics (rows of order 3, state [q; q̇; q̈]), plan_jerk_motion.
/// Problem::make_planner() (scenario/problem.hpp) is the one place that picks one; planning,
/// the closed loop, feasibility, the writers, `refdyn check` and the report use only this
/// interface and never ask for the order.
///
/// For both, the state starts with [q; q̇] and ẋ = derivative(t, x) holds [q̇; q̈; …], so the
/// reference a controller tracks is q̂ = x[0, n), q̂̇ = x[n, 2n), q̂̈ = ẋ[n, 2n) (reference()).

#include "refdyn/reference/jerk.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/trajectory.hpp"

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace refdyn {

/// The partition of the coordinates into independent and dependent ones (projection method).
struct PlannerPartition {
  std::vector<int> independent, dependent;
  double condition = 0;                   ///< cond(K_dc), 1-norm, at the last evaluation
};

/// One residual of the constraint rows at the last derivative(): a label ("|Phi|") and a value
/// per row.
struct RowResidual {
  std::string label;
  Eigen::VectorXd values;
};

class Planner {
 public:
  virtual ~Planner() = default;

  virtual const Model& model() const = 0;
  int nq() const { return model().nq; }
  /// Size of the planner's state x (its first 2n entries are [q; q̇]).
  virtual int state_size() const = 0;
  /// Names of the states after [q; q̇] (force-element states, or "acc_<joint>" for q̈).
  virtual std::vector<std::string> state_names() const = 0;
  /// Whether the state carries the acceleration q̈ (x[2n, 3n)): then an initial acceleration
  /// (a hint, see JerkDynamics::initial_state) is part of the initial conditions.
  virtual bool state_has_acceleration() const = 0;

  /// The initial state from the initial conditions: [q0; q̇0; z0] or [q0; q̇0; q̈0] (q̈0
  /// consistent with the dynamics; `qdd_hint`, when given and used, fixes its constrained part).
  virtual Eigen::VectorXd initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                        const Eigen::VectorXd* qdd_hint = nullptr) = 0;
  /// ẋ at (t, x). Throws NumericalFailure where the equations are singular.
  virtual void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) = 0;
  /// ∂ẋ/∂x at (t, x), exact (implicit integration, method bdf); J is resized and written. The
  /// default throws an Error saying the planner has none.
  virtual void jacobian(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J);
  /// Whether the planner's state is projected onto its constraints after each step
  /// (stabilization: projection or both), and the projection itself (the default: none).
  virtual bool projects() const { return false; }
  virtual void project(double /*t*/, Eigen::VectorXd& /*x*/) {}
  /// The reference a controller tracks at (x, ẋ): q̂ = x[0, n), q̂̇ = x[n, 2n), q̂̈ = ẋ[n, 2n).
  void reference(const Eigen::VectorXd& x, const Eigen::VectorXd& xdot, const double*& q, const double*& qd,
                 const double*& qdd) const {
    q = x.data();
    qd = x.data() + nq();
    qdd = xdot.data() + nq();
  }

  /// Integrates from x0 and records the plan (plan_motion or plan_jerk_motion).
  virtual Plan plan(const Eigen::VectorXd& x0, const PlanSettings& settings) = 0;
  /// Whether plan() cuts the plan at RecordOptions::residual_tolerance (a constraint residual
  /// max |Phi|); otherwise the tolerance is not used (the jerk plan reports its dynamics residual).
  virtual bool checks_residual_tolerance() const = 0;

  /// The constraint rows' residuals at the last derivative(), for `refdyn check`.
  virtual std::vector<RowResidual> row_residuals() const = 0;
  /// The coordinate partition at the last evaluation, or none (no partition: a KKT system).
  virtual std::optional<PlannerPartition> partition() const = 0;
  /// One line describing the planner's own settings for `refdyn check` ("" for none).
  virtual std::string description() const = 0;
};

/// The reference dynamics of order ≤ 2 (ReferenceDynamics) as a Planner.
class ReferencePlanner final : public Planner {
 public:
  /// Owns `rd`.
  explicit ReferencePlanner(std::unique_ptr<ReferenceDynamics> rd);
  /// Refers to `rd` (which must outlive the planner).
  explicit ReferencePlanner(ReferenceDynamics& rd);
  ReferenceDynamics& dynamics() { return *rd_; }
  void jacobian(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J) override { rd_->jacobian(t, x, J); }
  bool projects() const override { return rd_->options().stabilization != Stabilization::Baumgarte; }
  void project(double t, Eigen::VectorXd& x) override { rd_->project_state(t, x); }

  const Model& model() const override { return rd_->model(); }
  int state_size() const override { return rd_->state_size(); }
  std::vector<std::string> state_names() const override { return rd_->forces().state_names(); }
  bool state_has_acceleration() const override { return false; }
  /// rd.make_state(q0, qd0); the acceleration hint is not used.
  Eigen::VectorXd initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                const Eigen::VectorXd* qdd_hint = nullptr) override;
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) override { rd_->derivative(t, x, xdot); }
  Plan plan(const Eigen::VectorXd& x0, const PlanSettings& settings) override;
  bool checks_residual_tolerance() const override { return true; }
  /// |Phi| and |dPhi/dt| per row.
  std::vector<RowResidual> row_residuals() const override;
  std::optional<PlannerPartition> partition() const override;
  std::string description() const override { return ""; }

 private:
  std::unique_ptr<ReferenceDynamics> owned_;
  ReferenceDynamics* rd_;
};

/// The jerk dynamics (p = 3, JerkDynamics) as a Planner.
class JerkPlanner final : public Planner {
 public:
  explicit JerkPlanner(std::unique_ptr<JerkDynamics> jd);
  explicit JerkPlanner(JerkDynamics& jd);
  JerkDynamics& dynamics() { return *jd_; }

  const Model& model() const override { return jd_->model(); }
  int state_size() const override { return jd_->state_size(); }
  /// "acc_<joint>" per joint.
  std::vector<std::string> state_names() const override;
  bool state_has_acceleration() const override { return true; }
  Eigen::VectorXd initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                const Eigen::VectorXd* qdd_hint = nullptr) override {
    return jd_->initial_state(t0, q0, qd0, qdd_hint);
  }
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) override { jd_->derivative(t, x, xdot); }
  /// plan_jerk_motion (the residual tolerance applies to the rows of order ≤ 2).
  Plan plan(const Eigen::VectorXd& x0, const PlanSettings& settings) override;
  /// Rows of order ≤ 2 beside the jerk rows are checked (plan_jerk_motion); jerk rows alone are not.
  bool checks_residual_tolerance() const override {
    return static_cast<int>(jd_->constraints().size()) < jd_->num_constraints();
  }
  /// |B qddd + s| per row (jerk rows alone), else |Phi| and |dPhi/dt| (jerk rows: |B qddd + s|).
  std::vector<RowResidual> row_residuals() const override;
  std::optional<PlannerPartition> partition() const override { return std::nullopt; }
  /// "jerk-level problem (p = 3): state [q; qd; qdd], kappa = … 1/s".
  std::string description() const override;

 private:
  std::unique_ptr<JerkDynamics> owned_;
  JerkDynamics* jd_;
};

}  // namespace refdyn
