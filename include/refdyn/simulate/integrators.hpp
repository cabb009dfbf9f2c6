#pragma once
/// Time integration of ẋ = f(t, x): classical fixed-step RK4 (the paper's scheme), adaptive
/// Dormand–Prince 5(4) with dense output (Boost.Odeint), and implicit variable-order BDF (CVODE of
/// SUNDIALS 6, dense Newton iterations on the caller's exact Jacobian ∂f/∂x — no finite
/// differences) for stiff problems such as stiff LuGre bristles (docs/implicit.md). Numerical
/// outcomes are results: the Summary says whether the run reached t1 and, if not, when and why it
/// stopped; the state and everything observed up to then are kept.

#include "refdyn/common/fields.hpp"

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

namespace refdyn {

enum class IntegratorMethod { RK4, DormandPrince45, BDF };
/// "rk4", "dopri5", "bdf" (the scenario's integrator.method).
const char* to_string(IntegratorMethod m);
/// Whether an integrator's stages are recorded with a plan and replayed on the same grid by the
/// closed loop (simulate_closed_loop) and the sensitivity pass (plan_sensitivity): the one place
/// that says so. RK4 only: its fixed grid is known before the run; DOPRI5 and BDF choose their
/// steps as they go, so the closed loop integrates the planner jointly with the plant instead.
constexpr bool replays_stages(IntegratorMethod m) { return m == IntegratorMethod::RK4; }
/// The method named by to_string(m); false when `text` names none.
bool from_string(const std::string& text, IntegratorMethod& m);

struct IntegratorOptions {
  IntegratorMethod method = IntegratorMethod::RK4;
  double t0 = 0.0, t1 = 5.0;
  double step = 1e-3;            ///< RK4 step; initial step for Dormand–Prince; BDF: see output_interval [s]
  double output_interval = 0.0;  ///< observer sampling interval [s]; 0: every RK4 step (DP, BDF: `step`)
  double rtol = 1e-8, atol = 1e-10;  ///< Dormand–Prince and BDF tolerances (BDF: CVODE's scalar rtol, atol)
  double min_step = 1e-12;       ///< Dormand–Prince, BDF: smaller steps mean the run has collapsed
  long max_steps = 100'000'000;  ///< accepted steps over the whole run
  int max_order = 5;             ///< BDF: highest order, 1…5 (BDF1 = implicit Euler)
  /// Times in (t0, t1), increasing, where the right-hand side may jump (a time law's knots, where
  /// s̈ does): RK4 takes equal steps of at most `step` on each part between them (Rk4Grid), so
  /// its steps land on them; Dormand–Prince and BDF stop there and restart. A step that ends on
  /// a breakpoint evaluates its last stages at the double just below it (the left limit), the
  /// next step starts at the breakpoint itself. Empty: none (RK4's uniform grid).
  std::vector<double> breakpoints;
  /// Throws refdyn::Error naming the bad field.
  void validate() const;
};

enum class IntegrationStatus {
  Success,           ///< reached t1
  NonFinite,         ///< the state became NaN or infinite
  StepSizeCollapse,  ///< the adaptive step fell below min_step
  NumericalFailure,  ///< the right-hand side reported a failure (e.g. singular partition)
  MaxSteps,          ///< max_steps exhausted before t1
  Stopped,           ///< the observer asked to stop
  ResidualExceeded,  ///< a plan's constraint residual exceeded its tolerance (the plan misses its task)
  ReferenceStopped,  ///< a closed loop reached the end of a plan that itself stopped early
};
const char* to_string(IntegrationStatus s);
/// The status named by to_string(s); false when `text` names none.
bool from_string(const std::string& text, IntegrationStatus& s);

struct IntegrationSummary {
  IntegrationStatus status = IntegrationStatus::Success;
  std::string message;           ///< empty on success; else when and why it stopped
  long steps = 0;                ///< accepted steps
  long rejected_steps = 0;       ///< Dormand–Prince; BDF: error-test plus Newton-convergence failures
  long rhs_evaluations = 0;
  long jacobian_evaluations = 0; ///< BDF: evaluations of ∂f/∂x
  long newton_iterations = 0;    ///< BDF: nonlinear (Newton) iterations
  long newton_failures = 0;      ///< BDF: Newton iterations that did not converge (step retried smaller)
  long error_test_failures = 0;  ///< BDF: steps rejected by the local error test
  double t_end = 0.0;            ///< time of the last valid state
  double wall_time = 0.0;        ///< [s]
  double max_constraint_residual = 0.0;  ///< filled by callers that integrate constrained systems
  long projections = 0;          ///< stabilization by projection: steps whose state was corrected
  double max_projection_correction = 0.0;  ///< the largest correction ‖δq‖∞ or ‖δq̇‖∞ applied
  bool ok() const { return status == IntegrationStatus::Success; }
};

/// The plan summary's fields (summary.json "plan", the Python dicts; common/fields.hpp).
template <>
struct Fields<IntegrationSummary> {
  using S = IntegrationSummary;
  static constexpr auto list() {
    return std::make_tuple(field("status", &S::status),
                           field("message", &S::message),
                           field("steps", &S::steps),
                           field("rejected_steps", &S::rejected_steps),
                           field("rhs_evaluations", &S::rhs_evaluations, "", sink::Json | sink::Wire | sink::Python),
                           field("jacobian_evaluations", &S::jacobian_evaluations, "", sink::Json | sink::Wire | sink::Python),
                           field("newton_iterations", &S::newton_iterations, "", sink::Json | sink::Wire | sink::Python),
                           field("newton_failures", &S::newton_failures, "", sink::Json | sink::Wire | sink::Python),
                           field("error_test_failures", &S::error_test_failures, "", sink::Json | sink::Wire | sink::Python),
                           field("t_end", &S::t_end, "s"),
                           field("max_constraint_residual", &S::max_constraint_residual, "m or rad"),
                           field("projections", &S::projections, "", sink::Json | sink::Wire | sink::Python),
                           field("max_projection_correction", &S::max_projection_correction, "", sink::Json | sink::Wire | sink::Python),
                           field("wall_time", &S::wall_time, "s") | JsonKey{"wall_time_s"});
  }
};

/// ẋ = f(t, x); dx has the size of x.
using OdeRhs = std::function<void(double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx)>;
/// Called at t0 and every output sample; return false to stop.
using OdeObserver = std::function<bool(double t, const Eigen::VectorXd& x)>;

/// ∂f/∂x at (t, x), exact; J is resized to n×n and written (BDF's Newton iterations).
using OdeJacobian = std::function<void(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J)>;

/// Called after every accepted step with the new state, which it may correct in place (a
/// projection onto constraints, ReferenceDynamics::project_state). It throws NumericalFailure
/// when it cannot; the run then stops with that status. RK4 and Dormand–Prince continue from the
/// corrected state (Dormand–Prince's samples inside the step are its interpolant, before the
/// correction); BDF passes the correction to CVODE's projection (CVodeSetProjFn).
using OdeProjection = std::function<void(double t, Eigen::VectorXd& x)>;

/// Integrates from x (at options.t0) to options.t1; on return x holds the last valid state.
/// BDF needs `jacobian` (an Error without it); the other methods ignore it.
IntegrationSummary integrate(const OdeRhs& f, Eigen::VectorXd& x, const IntegratorOptions& options,
                             const OdeObserver& observer = {}, const OdeJacobian& jacobian = {},
                             const OdeProjection& projection = {});

/// Which evaluation of the right-hand side a call is: RK4 stage `stage` (0..3, at t, t + h/2,
/// t + h/2, t + h) of step `step` (0-based). Dormand–Prince: step = stage = −1 (odeint does not
/// say; its evaluations include rejected trial steps), and BDF likewise (Newton iterates).
struct Stage {
  long step = -1;
  int stage = -1;
};
/// ẋ = f(stage, t, x): the stage hook, for callers that record or replay stage values.
using OdeStageRhs = std::function<void(const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx)>;
/// integrate() with the stage identity passed to the right-hand side.
IntegrationSummary integrate_staged(const OdeStageRhs& f, Eigen::VectorXd& x, const IntegratorOptions& options,
                                    const OdeObserver& observer = {}, const OdeJacobian& jacobian = {},
                                    const OdeProjection& projection = {});

/// The RK4 grid of `o`: step k runs from start(k) to end(k) (end of the last: exactly t1).
/// Without breakpoints N = ⌈(t1 − t0)/step⌉ equal steps h = (t1 − t0)/N, start(k) = t0 + k h,
/// and every ⌊output_interval/h⌉-th step end is an output sample (output_interval 0: each).
/// With breakpoints b_1 < … < b_B each part [b_j, b_{j+1}] (b_0 = t0, b_{B+1} = t1) takes
/// ⌈(b_{j+1} − b_j)/step⌉ equal steps, so step ends land on the breakpoints; the output samples
/// are every step end for output_interval 0, else the first step end at or after each multiple of
/// output_interval past t0, and the last. stage_time(k, c) is the time of RK4's stage at
/// start(k) + c·h(k), never past t1 (start + h can round one ulp past it, and past t1 a time law
/// is at rest): with breakpoints the c = 1 stage is at end(k) itself, and just below end(k)
/// (std::nextafter) when end(k) is a breakpoint, the right-hand side's left limit there.
class Rk4Grid {
 public:
  explicit Rk4Grid(const IntegratorOptions& o);
  long steps() const { return steps_; }
  double start(long k) const { return times_.empty() ? t0_ + k * h_ : times_[static_cast<size_t>(k)]; }
  double end(long k) const {
    return k + 1 == steps_ ? t1_ : times_.empty() ? t0_ + (k + 1) * h_ : times_[static_cast<size_t>(k) + 1];
  }
  double size(long k) const { return times_.empty() ? h_ : steps_h_[static_cast<size_t>(k)]; }
  double stage_time(long k, double c) const;
  bool sample(long k) const {  ///< end(k) is an output sample
    return times_.empty() ? (k + 1) % every_ == 0 || k + 1 == steps_ : samples_[static_cast<size_t>(k)] != 0;
  }
  /// The part (0 … B) that step k lies in, and its first step (with breakpoints; else 0).
  int part(long k) const { return parts_.empty() ? 0 : parts_[static_cast<size_t>(k)]; }
  bool uniform() const { return times_.empty(); }
  double uniform_step() const { return h_; }  ///< h of the uniform grid (no breakpoints)

 private:
  double t0_ = 0, t1_ = 0, h_ = 0;
  long steps_ = 0, every_ = 1;
  std::vector<double> times_, steps_h_;  ///< with breakpoints: step starts (and t1), step sizes
  std::vector<char> samples_, ends_on_break_;
  std::vector<int> parts_;
};

/// One classical RK4 step of size h in place, with caller-provided scratch (k1..k4, tmp: size
/// of x). No heap allocation.
struct Rk4Workspace {
  explicit Rk4Workspace(Eigen::Index n);
  Eigen::VectorXd k1, k2, k3, k4, tmp;
};
void rk4_step(const OdeRhs& f, double t, double h, Eigen::VectorXd& x, Rk4Workspace& ws);

}  // namespace refdyn
