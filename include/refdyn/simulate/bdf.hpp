#pragma once
/// Implicit, adaptive integration of x' = f(t, x) by CVODE's variable-order BDF (SUNDIALS 6,
/// Debian libsundials-dev) with a dense Newton solver and an exact Jacobian ∂f/∂x supplied by
/// the caller (no finite differences: when no Jacobian is given the call is refused). For stiff
/// systems (e.g. LuGre bristles with σ0 ~ 1e5), where explicit RK4 / Dormand–Prince need tiny steps.
/// Issue 21, work in progress: this is the integrator only; the Jacobian of the reference dynamics
/// comes from the generic core.

#include <Eigen/Dense>

#include <functional>
#include <string>
#include <vector>

namespace refdyn {

struct BdfOptions {
  double rtol = 1e-6;
  double atol = 1e-9;
  int max_order = 5;        ///< 1..5
  long max_steps = 1000000; ///< internal steps over the whole span
  double initial_step = 0;  ///< 0: CVODE's estimate
  double min_step = 0;
  double max_step = 0;      ///< 0: unbounded
};

/// CVODE's counters after a run.
struct BdfCounters {
  long steps = 0, rhs_evaluations = 0, jacobian_evaluations = 0, newton_iterations = 0;
  long newton_failures = 0, error_test_failures = 0;
  int last_order = 0;
  double last_step = 0;
};

struct BdfResult {
  std::vector<double> t;             ///< output times reached (t0 first)
  std::vector<Eigen::VectorXd> x;    ///< the state at each
  BdfCounters counters;
  bool ok = false;
  std::string message;               ///< why it stopped early (CVODE's flag, in words)
};

using BdfRhs = std::function<void(double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx)>;
using BdfJacobian = std::function<void(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J)>;

/// Integrates from (t0, x0) and records the state at each time of `outputs` (increasing, > t0).
/// Throws Error on invalid options; a failure during the run is reported in the result.
BdfResult integrate_bdf(const BdfRhs& f, const BdfJacobian& jacobian, double t0, const Eigen::VectorXd& x0,
                        const std::vector<double>& outputs, const BdfOptions& options = {});

}  // namespace refdyn
