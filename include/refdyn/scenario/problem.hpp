#pragma once
/// A Problem is a scenario built: the model, its constraints and forces, the reference-dynamics
/// options, a consistent initial state, the integrator and the closed-loop experiments, every
/// number evaluated and every name bound. build_problem(spec) makes one from a ScenarioSpec
/// (spec.hpp) and checks everything a run needs at t0 (constraint residuals, the partition),
/// so that a Problem that exists can be planned.
///
///   ScenarioSpec ──build_problem──▶ Problem ──plan_problem──▶ Plan (a Trajectory)
///                                          └──track_experiment──▶ ClosedLoopResult (a Trajectory)

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/planner.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/reference/jerk.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/scenario/spec.hpp"

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace refdyn {

/// Resource limits checked by build_problem before any work, so that a scenario that would run
/// for hours or exhaust memory is rejected at once with the key to change (scenario `limits:`).
struct Limits {
  long max_steps = 2'000'000;    ///< integration steps of one run (RK4: (t1 − t0)/step; DOPRI5: a stop)
  long max_samples = 1'000'000;  ///< recorded output samples of one run
  long max_runs = 10'000;        ///< closed-loop runs (or variants) after expanding sweeps, grids and Monte Carlo samples; at most kMaxRunsCeiling
};

/// The largest limits.max_runs a scenario may set (building 100,000 runs takes ~5 s, ~0.3 GB).
inline constexpr long kMaxRunsCeiling = 100'000;
/// Most values of a list parameter (`v: [0.5, …]`, docs/scenario.md "parameters"): a time law of
/// 100,000 parts already needs more steps than limits.max_steps allows at any useful step.
inline constexpr size_t kMaxListParameter = 100'000;
/// Default of `integrator.residual_tolerance`: the largest constraint residual max |Phi| (metres
/// or radians, as the constraints are written) a plan may reach before it is cut. Far above the
/// residuals of a plan that meets its task (examples and tests: below 1e-5), far below a plan
/// that has left it (a diverging plan, a step too large for the motion).
inline constexpr double kDefaultResidualTolerance = 1e-3;

/// One closed-loop run of a scenario (one value of a sweep, one point of a grid, one Monte Carlo
/// sample, or an experiment with none of them). Everything a run needs is fixed here, by
/// build_problem, so runs may be executed in any order or in parallel with the same results.
struct Experiment {
  std::string name;
  /// The run's own parameters and their values, in the order written: the sweep parameter, the
  /// grid's parameters, or the Monte Carlo distributions (values as drawn). Empty: none.
  std::vector<std::pair<std::string, double>> sweep;
  long sample = -1;                         ///< Monte Carlo: the sample index 0 … samples − 1; −1: not Monte Carlo
  std::uint64_t seed = 0;                   ///< Monte Carlo: the experiment's seed (0 when sample < 0)
  Eigen::VectorXd q0, qd0;                  ///< plant initial state
  ForceSet plant_forces;                    ///< the plant's own force elements
  std::string controller_type;
  ControllerFactory make_controller;        ///< builds the controller for a model
};

/// A built scenario. Not movable: ReferenceDynamics objects made from it refer to its members.
struct Problem {
  explicit Problem(Model m) : model(std::move(m)) {}
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;

  std::string file;
  std::string name;
  std::map<std::string, double> parameters;
  /// The scenario's texts of what sensitivities differentiate through besides the equations
  /// (symbolic/sensitivity.hpp): each parameter's definition in order (a variant's value as a
  /// number), initial.q and initial.qd per joint ("" where not written) and integrator.t0/t1.
  struct SourceTexts {
    std::vector<std::pair<std::string, std::string>> parameters;
    std::vector<std::string> q0, qd0;
    std::string t0, t1;
  };
  SourceTexts texts;
  const Model model;
  ForceSet forces;
  ConstraintSet constraints;
  ReferenceDynamicsOptions options;         ///< with the partition fixed (chosen at t0 when automatic)
  bool automatic_independent = false;       ///< the partition was chosen automatically
  Eigen::VectorXd q0, qd0;                  ///< consistent reference initial state
  bool project_initial = false;             ///< (q0, qd0) were projected onto the constraints
  double initial_tolerance = 1e-8;
  Eigen::VectorXd initial_dq, initial_dqd;  ///< the projection's correction (zeros if none)
  IntegratorOptions integrator;
  double residual_from = 0.0;               ///< report max residual over t >= this
  /// The knot times t_0 = 0, t_1, …, t_K of the scenario's time law (empty: none); the parts
  /// of the per-part metrics (simulate/metrics.hpp).
  std::vector<double> time_law_knots;
  /// The scenario's time law itself (null: none): the sensitivities evaluate it and its
  /// derivatives in its numbers natively (symbolic/sensitivity.hpp).
  TimeLawPtr time_law;
  /// integrator.t1 was written `end`: t1 is the time law's end and moves with its numbers.
  bool t1_is_law_end = false;
  /// The plan stops (status ResidualExceeded, exit 4) at the first sample with t >= residual_from
  /// whose constraint residual max |Phi| exceeds this: beyond it the plan no longer meets its
  /// task (`integrator.residual_tolerance`, docs/scenario.md).
  double residual_tolerance = kDefaultResidualTolerance;
  Eigen::VectorXd effort_limit;             ///< closed-loop saturation (empty: none)
  /// The plant of the closed loops (docs/scenario.md, "The plant"): the material rows of
  /// `constraints` (null when there are none) and the motors with the coordinates the
  /// controllers assign (`actuators`, every joint by default), checked at the initial state.
  std::shared_ptr<const ConstraintSet> material;
  Actuation actuation;
  std::vector<std::unique_ptr<Experiment>> experiments;
  std::vector<std::string> report_points;   ///< points recorded in trajectories
  /// The numbers of the scenario's `model:` section (dh: or links:) as read, with their texts,
  /// for generate_symbolic, which keeps the parameters symbolic; empty for a URDF model or a
  /// Problem built in C++ (then the compiled model's numbers are used).
  std::optional<ModelNumbers> model_numbers;
  /// What reading the model found worth saying, one line each (ModelSpec::notes, and an armature
  /// of model.armature that replaces a URDF's): `refdyn check` prints them as notes.
  std::vector<std::string> model_notes;
  /// The visual geometry of the model's links (a URDF's <visual>s, meshes resolved; the report
  /// draws them on the link frames, Model::frame_*).
  std::vector<VisualSpec> visuals;
  Limits limits;
  /// Jerk-level problems (a constraint of `order: jerk`, docs/higher_order.md): their jerk rows
  /// (`constraints` has every row, of any order), the gain κ and the initial acceleration. They
  /// are planned by JerkDynamics (state [q; q̇; q̈; z]) with `forces` and the Baumgarte gains of
  /// `options`; the partition is not used (a KKT system with M).
  std::vector<JerkConstraintPtr> jerk_constraints;
  double kappa = 50.0;
  Eigen::VectorXd qdd0;                     ///< the hint (initial.qdd); empty: the free acceleration
  /// initial.qdd: {consistent_with: [rows]}: jerk rows whose q̈0 satisfies their source row.
  std::vector<std::string> qdd_consistent_with;
  /// The JerkDynamics options of a jerk problem (κ, the Baumgarte gains, consistent_with).
  JerkDynamicsOptions jerk_options() const;
  bool is_jerk_problem() const { return !jerk_constraints.empty(); }

  std::vector<int> report_point_indices() const;
  /// A reference dynamics of order ≤ 2 of this problem (refers to its members).
  std::unique_ptr<ReferenceDynamics> make_reference_dynamics() const;
  /// The planner of this problem (refers to its members): a JerkPlanner for a jerk problem,
  /// else a ReferencePlanner owning a new ReferenceDynamics, or, given `rd` (made by
  /// make_reference_dynamics()), one that uses `rd`. The one place that looks at the order.
  std::unique_ptr<Planner> make_planner(ReferenceDynamics* rd = nullptr) const;
  /// The initial conditions as a planner state: planner.initial_state(t0, q0, qd0, hint).
  Eigen::VectorXd initial_state(Planner& planner) const;
  /// What plan_problem plans with: the integrator, residual window and tolerance, points.
  PlanSettings plan_settings(const std::function<void(double)>& progress = {}) const;
};

/// A SpecReader of the scenario's file with its parameters evaluated (in order; each may use
/// the ones before it) and `deg`: what build_problem starts from.
SpecReader parameter_reader(const ScenarioSpec& spec);

/// A name that becomes part of a file or folder name (an experiment's track_<name>.csv, a
/// variant's folder): printable, letters, digits and . _ - + = only, not starting with . or -.
/// Fails with "… the <what> name '…' …".
void check_output_name(const SpecReader& c, const SpecValue& at, const std::string& key, const std::string& name,
                       const std::string& what);
/// `{parameter}` in a name template replaced by the value (printf %g).
std::string substitute_value(std::string name_template, const std::string& parameter, double value);

/// Builds and checks a Problem. Throws Error "FILE:LINE: KEY: message" naming the offending key.
std::unique_ptr<Problem> build_problem(const ScenarioSpec& spec);

/// Plans the problem's reference motion with `planner` (made by problem.make_planner()) from the
/// problem's initial conditions and plan_settings().
Plan plan_problem(const Problem& problem, Planner& planner, const std::function<void(double)>& progress = {});
/// The same with `rd` made by problem.make_reference_dynamics() (a jerk problem is planned by
/// its own JerkPlanner; `rd` is then not used).
Plan plan_problem(const Problem& problem, ReferenceDynamics& rd, const std::function<void(double)>& progress = {});

/// Runs one experiment on the unconstrained plant tracking `plan` (`planner`: the problem's,
/// used by Dormand–Prince to integrate the reference jointly).
ClosedLoopResult track_experiment(const Problem& problem, const Experiment& experiment, const Plan& plan,
                                  Planner& planner, const std::function<void(double)>& progress = {});
ClosedLoopResult track_experiment(const Problem& problem, const Experiment& experiment, const Plan& plan,
                                  ReferenceDynamics& rd, const std::function<void(double)>& progress = {});

}  // namespace refdyn
