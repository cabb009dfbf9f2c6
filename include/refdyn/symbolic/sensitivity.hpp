#pragma once
/// Forward sensitivities of a plan with respect to named scenario parameters
/// (docs/sensitivity.md): S(t) = ∂x(t)/∂p along the planned motion, and from it
/// the derivatives of the plan's metrics (simulate/metrics.hpp).
///
/// The derivatives are exact: ∂f/∂p comes from the reference dynamics in GiNaC
/// (generate_symbolic, with the parameters kept as symbols and differentiated), ∂f/∂x from the
/// same expressions; both are compiled to evaluation tapes once. The sensitivity of an RK4 plan
/// is the derivative of the RK4 solution itself (the variational equations integrated with the
/// plan's own stages), so it agrees with central differences of whole plans to their rounding.
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/metrics.hpp"

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

struct SensitivityOptions {
  std::vector<std::string> parameters;  ///< scenario parameters p (names), at least one
};

/// ∂(plan)/∂p at every sample of the plan.
struct PlanSensitivity {
  std::vector<std::string> parameters;
  std::vector<double> t;                    ///< the plan's samples
  std::vector<Eigen::MatrixXd> dx;          ///< per sample: ∂[q; q̇; z]/∂p (state_size × np)
  std::vector<Eigen::MatrixXd> dqdd;        ///< per sample: ∂q̈/∂p (n × np)
  std::vector<Eigen::MatrixXd> deffort;     ///< per sample: ∂τ/∂p of the actuator effort (n × np)
  std::vector<Eigen::MatrixXd> dphi;        ///< per sample: ∂Φ/∂p of the constraint rows (m × np)
  Eigen::RowVectorXd dt_end;                ///< ∂t_end/∂p (a final time written with a parameter)
  /// per sample: ∂t/∂p of its time (the grid moves with t1 and, on a time law's knots, with each
  /// knot: IntegratorOptions::breakpoints); the columns of dx, dqdd, … are total derivatives at
  /// the moving sample.
  std::vector<Eigen::RowVectorXd> dt;
  double seconds = 0;                       ///< wall time of the sensitivity computation
};

/// Throws Error when the sensitivities of `problem`'s plan cannot be computed: an unknown or
/// repeated parameter name ("did you mean"), none, a jerk problem, a method other than RK4, a
/// stabilization other than Baumgarte, a constraint kind or force element without a symbolic form.
/// Called by plan_sensitivity; callers check before planning to fail before writing anything.
void check_sensitivity_request(const Problem& problem, const SensitivityOptions& options);

/// The sensitivities of `plan` (made by plan_problem from `problem`) at its samples. Throws as
/// check_sensitivity_request does, and NumericalFailure where the plan's equations are singular.
PlanSensitivity plan_sensitivity(const Problem& problem, const Plan& plan, const SensitivityOptions& options);

/// d(metric)/dp for each metric (the same order as `metrics`): rows of an (metrics × np) matrix.
Eigen::MatrixXd metric_gradients(const Problem& problem, const Plan& plan, const PlanSensitivity& sensitivity,
                                 const std::vector<Metric>& metrics);

}  // namespace refdyn
