#pragma once
/// `refdyn optimize`: choose task parameters of a scenario (its `optimize:` section,
/// docs/optimize.md) by planning candidates with NLopt. Shaped like Ceres' Solve: options in,
/// a summary out.
///
///   ScenarioSpec ──check_optimize──▶ OptimizeSetup (bounds, start, compiled expressions)
///   for each candidate x: io::variant_spec(x) ──build_problem──▶ Problem ──plan_problem──▶ Plan
///        ──plan_metrics──▶ metrics ──expressions──▶ objective, constraints (g ≤ 0)
///        (slsqp / mma: + plan_sensitivity + metric_gradients, chained through the expressions)
///
/// A candidate whose build or plan fails is a failed evaluation (a row with its reason), never
/// an exception out of the optimizer. The same x is planned once (NLopt asks for the objective
/// and the constraints separately).
#include "refdyn/common/fields.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/scenario/spec.hpp"

#include <atomic>
#include <functional>
#include <memory>
#include <limits>
#include <string>
#include <vector>

namespace refdyn {

/// PhasePlane: the fastest knot-speed time law by TOPP-RA (optimize/phase_plane.hpp), no NLopt.
enum class OptimizeMethod { Slsqp, Mma, Cobyla, Bobyqa, PhasePlane };
const char* to_string(OptimizeMethod m);
/// "slsqp" | "mma" | "cobyla" | "bobyqa" | "phase_plane"; Error otherwise (with "did you mean").
OptimizeMethod optimize_method(const std::string& name);
/// Gradient-based (needs the plan's sensitivities).
inline bool uses_gradients(OptimizeMethod m) { return m == OptimizeMethod::Slsqp || m == OptimizeMethod::Mma; }

/// One inequality constraint g(x) ≤ 0 of the optimization.
struct OptimizeConstraint {
  std::string name;         ///< column name: "velocity(psi1)", "effort(z3)", "upper(z3)", "bounds[0].upper"
  std::string metric;       ///< feasible: the metric it bounds; bounds: empty (see expression)
  int expression = -1;      ///< bounds: index into OptimizeSetup::bounds; −1 for a limit
  double limit = 0;         ///< the bound
  double scale = 1;         ///< |limit| (1 when the limit is 0)
  bool upper = true;        ///< value ≤ limit (else value ≥ limit)
};

/// The `optimize:` section checked against the scenario: every number evaluated, every name
/// bound, the expressions compiled over (metric names…, variable names…) with derivative order 1.
struct OptimizeSetup {
  /// Every scalar variable; a list parameter `v` of n values is n of them, named v[1] … v[n].
  std::vector<std::string> variables;
  /// The list variables: name, index of their first element in `variables`, length.
  struct ListVariable {
    std::string name;
    size_t first = 0, size = 0;
  };
  std::vector<ListVariable> lists;
  std::vector<SourceLocation> variable_where;
  std::vector<double> lower, upper, start;
  OptimizeMethod method = OptimizeMethod::Slsqp;
  bool maximize = false;
  std::vector<std::string> metric_names;            ///< the expressions' first variables
  std::vector<bool> metric_used;                    ///< named by an expression or a limit (differentiated)
  std::shared_ptr<const Expression> objective;
  std::vector<std::shared_ptr<const Expression>> bounds;
  std::vector<OptimizeConstraint> constraints;
  bool feasible = false;                            ///< constraints.feasible
  double xtol = 1e-6, ftol = 1e-9;
  long budget = 100;
};

/// Checks the scenario's `optimize:` section against `base` (the scenario built as written):
/// unknown variable (did you mean), lower > upper, start outside the bounds, an expression
/// naming an unknown metric, a budget ≤ 0, … as Error "FILE:LINE: optimize.…: message".
OptimizeSetup check_optimize(const ScenarioSpec& spec, const Problem& base);

/// One planned candidate (a row of optimization.csv).
struct OptimizeEvaluation {
  long index = 0;
  std::vector<double> x;
  double objective = 0;                 ///< the expression's value (not negated for maximize)
  std::vector<double> constraints;      ///< g ≤ 0, scaled (value − limit)/|limit|
  bool ok = false;                      ///< built and planned to the end
  bool feasible = false;                ///< ok and every g ≤ 0
  std::string reason;                   ///< why it failed (empty when ok)
  double seconds = 0;
};

struct OptimizeOptions {
  std::string method;                   ///< empty: the scenario's
  long budget = 0;                      ///< > 0: overrides the scenario's
  /// Called after each new evaluation (from the optimizer's thread).
  std::function<void(const OptimizeEvaluation&, long budget)> progress;
  /// Set (e.g. by a SIGINT handler) to stop before the next plan; the best point so far is kept.
  const std::atomic<bool>* stop = nullptr;
};

struct OptimizeSummary {
  std::string method;
  bool maximize = false;                ///< the objective's sense
  std::string status;                   ///< success | xtol_reached | ftol_reached | budget | stopped | failure | roundoff_limited
  std::string message;
  long evaluations = 0;                 ///< plans made (each distinct x once)
  std::vector<std::string> variables;
  std::vector<std::string> constraint_names;
  std::vector<double> best_x;           ///< the best feasible point (else the least infeasible one)
  double best_objective = 0;
  bool feasible = false;                ///< best_x is feasible
  bool stopped = false;                 ///< OptimizeOptions::stop was set
  std::vector<OptimizeEvaluation> history;
  /// Seconds: optimize_scenario's own time; `refdyn optimize` sets it to the whole command's
  /// (reading the file to writing the outputs).
  double wall_time = 0;
  /// method phase_plane: the path's time optimum T* under the joints' limits, estimated
  /// (phase_plane_time_optimum), against which the answer's t_end is judged; NaN otherwise.
  double time_optimum = std::numeric_limits<double>::quiet_NaN();
  /// Where the time went, in order (seconds): optimize_scenario adds setup (build + check), path,
  /// time_optimum and topp_ra (phase_plane), plans (every candidate's build + plan + metrics) and optimizer (the
  /// whole search, plans included); `refdyn optimize` adds load, check, final_plan and write.
  std::vector<std::pair<std::string, double>> phases;
  JsonValue to_json() const;            ///< summary.json's "optimization" object
};

struct OptimizeResult {
  OptimizeSetup setup;
  OptimizeSummary summary;
  ScenarioSpec best_spec;               ///< the scenario with best_x set (no optimize/variants sections)
};

/// `spec` with the variables set to `x` (io::variant_spec), without optimize: and variants:.
ScenarioSpec spec_at(const ScenarioSpec& spec, const std::vector<std::string>& variables, const std::vector<double>& x);

/// Runs the optimization of `spec` (which must have an `optimize:` section). Throws Error for a
/// bad section (check_optimize) or when a gradient method cannot differentiate the plan.
OptimizeResult optimize_scenario(const ScenarioSpec& spec, const OptimizeOptions& options = {});

/// optimization.csv: index, the variables, objective, the constraints, feasible, status, reason.
std::string optimization_csv(const OptimizeSummary& summary);

/// The scenario text with the value of each variable replaced where the reader recorded it
/// (`root`: the text as parsed, ScenarioSpec::root; line and column of each parameter's value),
/// block or flow style; a list variable's elements (names v[1] … v[n]) in place in its list, so
/// the compact form stays compact. Comments and the rest of the text are kept (the spaces before
/// a comment after the value are padded or shrunk so the comment stays in its column). Error when
/// a name is no parameter or its value is not a plain one-line value. Linear in the text's size.
std::string optimized_yaml(const std::string& text, const SpecValue& root, const std::vector<std::string>& names,
                           const std::vector<double>& values);
/// The same, parsing `text` first (io::parse_yaml_tree).
std::string optimized_yaml(const std::string& text, const std::vector<std::string>& names, const std::vector<double>& values);

// The fields of the optimization's outputs (common/fields.hpp): summary.json's "optimization"
// object (OptimizeSummary::to_json) and the rows of optimization.csv (optimization_csv, whose
// vector fields are named by the summary's variables and constraint names: io::ColumnLists).
template <>
struct Fields<OptimizeSummary> {
  using S = OptimizeSummary;
  static std::string sense(const S& s) { return s.maximize ? "maximize" : "minimize"; }
  /// The best point, variable → value.
  static std::vector<std::pair<std::string, double>> best(const S& s) {
    std::vector<std::pair<std::string, double>> b;
    for (size_t i = 0; i < s.variables.size() && i < s.best_x.size(); ++i) b.emplace_back(s.variables[i], s.best_x[i]);
    return b;
  }
  static constexpr unsigned in = sink::Json;
  static constexpr auto list() {
    return std::make_tuple(field("method", &S::method, "", in), derived("sense", &sense, "", in),
                           field("status", &S::status, "", in), field("message", &S::message, "", in),
                           field("evaluations", &S::evaluations, "", in), derived("best", &best, "", in),
                           field("best_objective", &S::best_objective, "", in) | JsonKey{"objective"},  // null when not finite
                           field("feasible", &S::feasible, "", in),
                           field("constraint_names", &S::constraint_names, "", in) | JsonKey{"constraints"},
                           field("time_optimum", &S::time_optimum, "s", in) | JsonKey{"time_optimum_s"},  // null: not phase_plane
                           field("wall_time", &S::wall_time, "s", in) | JsonKey{"wall_time_s"},
                           field("phases", &S::phases, "s", in) | JsonKey{"phases_s"});
  }
};
template <>
struct Fields<OptimizeEvaluation> {
  using S = OptimizeEvaluation;
  static std::string status(const S& e) { return e.ok ? "ok" : "failed"; }
  static constexpr unsigned in = sink::Csv;
  static constexpr auto list() {
    return std::make_tuple(field("index", &S::index, "", in), field("x", &S::x, "", in),
                           field("objective", &S::objective, "", in), field("constraints", &S::constraints, "", in),
                           field("feasible", &S::feasible, "", in), derived("status", &status, "", in),
                           field("reason", &S::reason, "", in));
  }
};

}  // namespace refdyn
