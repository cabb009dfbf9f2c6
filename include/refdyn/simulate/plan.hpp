#pragma once
/// Planning: the reference dynamics (of order ≤ 2, or the jerk dynamics of order 3) integrated
/// from a consistent initial state and recorded as a Plan (trajectory.hpp). Callers that should
/// not care about the order use the Planner interface (planner.hpp), which calls these.

#include "refdyn/reference/jerk.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/simulate/trajectory.hpp"

#include <functional>
#include <utility>

namespace refdyn {

/// How a plan is made and recorded: the one settings argument of plan_motion, plan_jerk_motion
/// and Planner::plan. `plan_motion(rd, x0, {integrator})`, `{integrator, 0.5}`,
/// `{integrator, 0.5, record}`; the fields may also be set one by one.
struct PlanSettings {
  PlanSettings(IntegratorOptions integrator_ = {}, double residual_from_ = 0.0, RecordOptions record_ = {},
               std::function<void(double)> progress_ = {})
      : integrator(std::move(integrator_)), residual_from(residual_from_), record(std::move(record_)),
        progress(std::move(progress_)) {}
  IntegratorOptions integrator;
  double residual_from = 0.0;             ///< the residual is reported (and checked) for t >= this
  RecordOptions record;                   ///< recorded points, residual tolerance
  std::function<void(double)> progress;   ///< optional: called with the time of every sample
};

/// Solves the reference dynamics from x0 with the given integrator and records it: at every
/// output sample one evaluation of the reference dynamics gives q̈, Φ, Φ̇, λ, Q_c, the efforts,
/// the recorded points and signals; for RK4 the integrator's stage hook also records the stage
/// values used by simulate_closed_loop. summary.max_constraint_residual is the largest |Φ| / |c|
/// over the samples with t >= residual_from. A sample (t >= residual_from) whose residual
/// exceeds record.residual_tolerance is not recorded: the plan ends before it (status
/// ResidualExceeded).
Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const PlanSettings& settings);

/// Integrates a JerkDynamics from x0 = [q; q̇; q̈; z] and records it through the same recorder
/// as plan_motion: x (with state_names "acc_<joint>" for the q̈ part, then the force elements'
/// states), q̈, per row Φ and Φ̇ (JerkDynamics::row_residual, row_rate_residual: jerk rows
/// B q⃛ + s in both), λ, Q_c = M q̈ − F, the actuator effort (Q_c minus the material rows'
/// reactions, plus the actuator force elements), the reactions of material rows, the force
/// elements' signals (a drive's ψ_dr, torque), recorded targets, points, and with RK4 the stages
/// [q̂, q̂̇, q̂̈] for tracking. Rows of order ≤ 2 are checked against record.residual_tolerance from
/// t >= residual_from (the plan ends before the first sample beyond it, status
/// ResidualExceeded). summary.max_constraint_residual: the largest of the dynamics residual
/// ‖R − Gᵀλ‖∞ and the rows' residuals over the samples.
Plan plan_jerk_motion(JerkDynamics& jd, const Eigen::VectorXd& x0, const PlanSettings& settings);

}  // namespace refdyn
