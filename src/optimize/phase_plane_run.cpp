// refdyn optimize, method phase_plane (docs/optimize.md): TOPP-RA on the time law's knots,
// checked by refdyn's own plan of the answer.
#include "evaluator.hpp"

namespace refdyn::optimize_detail {

namespace {

/// The seconds since t0.
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// What is wrong with the method: located at optimize.method, or said of --method.
struct MethodFailure {
  const OptimizeSpec& o;
  const SpecReader& c;
  bool from_cli;
  [[noreturn]] void operator()(const std::string& msg) const {
    if (from_cli) throw Error("--method phase_plane: " + msg);
    c.fail(o.method_value, "optimize.method", msg);
  }
};

/// Checks that the section asks what phase_plane answers: a law of the knot_speeds form, t_end
/// minimized, the joints' limits, no bounds on metrics.
void check_section(const ScenarioSpec& spec, const SpecReader& c, const MethodFailure& fail_method) {
  const OptimizeSpec& o = *spec.optimize;
  const SpecValue& tl = spec.time_law;
  if (!tl.is_map() || !tl["knot_speeds"])
    fail_method("phase_plane retimes a time law of the knot_speeds form (time_law: {task_duration, knot_speeds: [v1, …]}), "
           "and this scenario has " + std::string(tl ? "the segments form" : "no time_law") + " (docs/optimize.md)");
  if (o.maximize || trimmed(o.objective) != "t_end")
    c.fail(o.objective_value, "optimize.objective",
           "phase_plane minimizes t_end (the end of the time law), not '" + o.objective + "'; for another objective use slsqp or cobyla");
  if (!o.feasible)
    c.fail(o.value["constraints"] ? o.value["constraints"] : o.method_value, "optimize.constraints",
           "phase_plane needs constraints: {feasible: true}: the joints' effort and speed limits are what it retimes against");
  if (!o.bounds.empty())
    c.fail(o.bounds[0].value, o.bounds[0].key,
           "phase_plane takes no bounds on metrics, only the joints' limits (feasible: true); use slsqp or cobyla");
}

/// The variable of each knot speed, in order; checks that every variable is a knot speed and that
/// the task's duration uses none.
std::vector<size_t> knot_speed_variables(const ScenarioSpec& spec, const OptimizeSetup& s, const SpecReader& c) {
  const OptimizeSpec& o = *spec.optimize;
  const SpecValue& tl = spec.time_law;
  const SpecValue& ks = tl["knot_speeds"];
  std::vector<size_t> var_of;
  std::vector<bool> used(s.variables.size(), false);
  if (ks.is_scalar()) {  // the compact form: knot_speeds: v, a list parameter, one vector variable
    const std::string name = trimmed(ks.text);
    const auto it = std::find_if(s.lists.begin(), s.lists.end(), [&](const auto& l) { return l.name == name; });
    if (it == s.lists.end())
      c.fail(ks, "time_law.knot_speeds",
             "phase_plane chooses every knot speed, and the list parameter '" + name +
                 "' is not a variable of optimize.variables (hint: add - {name: " + name + ", lower: 0.05, upper: 10})");
    for (size_t i = 0; i < it->size; ++i) var_of.push_back(it->first + i);
  } else {
    for (size_t i = 0; i < ks.size(); ++i) {
      const std::string name = trimmed(ks[i].text);
      const auto it = std::find(s.variables.begin(), s.variables.end(), name);
      if (it == s.variables.end())
        c.fail(ks[i], "time_law.knot_speeds[" + std::to_string(i) + "]",
               "phase_plane chooses every knot speed, and '" + ks[i].text +
                   "' is not a variable of optimize.variables (hint: make it a parameter and add - {name: " + name +
                   ", lower: 0.01, upper: 10})");
      var_of.push_back(static_cast<size_t>(it - s.variables.begin()));
    }
  }
  for (size_t i : var_of) used[i] = true;
  for (size_t k = 0; k < used.size(); ++k)
    if (!used[k]) {
      size_t el = 0;
      std::string name = list_element(s.variables[k], el);
      if (name.empty()) name = s.variables[k];
      const auto v = std::find_if(o.variables.begin(), o.variables.end(), [&](const auto& x) { return x.name == name; });
      c.fail(v->value["name"], v->key + ".name",
             "phase_plane chooses only the knot speeds of the time law, and '" + name + "' is not one of them");
    }
  const SpecValue& Tp = tl["task_duration"];
  for (const auto& v : s.variables)
    if (uses_identifier(Tp.text, v))
      c.fail(Tp, "time_law.task_duration", "phase_plane keeps the task's own duration: it must not use the variable '" + v + "'");
  return var_of;
}

/// The task planned in its own time (no law, t1 = task_duration, the initial velocity projected).
struct OwnTimePlan {
  std::unique_ptr<Problem> problem;
  Plan plan;
};

/// The task in its own time, sampled on the law's knots and densely between them: m equal steps
/// per part of task time Δτ = Tp/K, m = max(16, ⌈4Δτ/step⌉) (the limits are imposed at these
/// samples; between them the effort differs from a sample's by O(δτ²), ~1e-7 relative here, so
/// that a plan of the answer at any step ≤ `step` stays within the limits to 1e-6).
OwnTimePlan plan_own_time(const ScenarioSpec& spec, const OptimizeSetup& s, const SpecReader& c, size_t K,
                          const MethodFailure& fail_method) {
  const SpecValue& Tp = spec.time_law["task_duration"];
  ScenarioSpec own = spec_at(spec, s.variables, s.start);
  own.time_law = SpecValue{};
  own.integrator.t1 = SpecValue::scalar(Tp.text, Tp.where);
  own.initial.project = true;
  {
    const double step = spec.integrator.step ? c.number(spec.integrator.step, "integrator.step") : IntegratorOptions{}.step;
    const double dtau = c.number(Tp, "time_law.task_duration") / static_cast<double>(K);
    const double m = std::max(16.0, std::ceil(4 * dtau / step - 1e-9));
    own.integrator.step = SpecValue::scalar(symbolic_number(dtau / m), spec.integrator.step.where);
  }
  OwnTimePlan out;
  try {
    out.problem = build_problem(own);
    auto planner = out.problem->make_planner();
    out.plan = plan_problem(*out.problem, *planner);
  } catch (const Error& e) {
    fail_method(std::string("phase_plane plans the task in its own time (no time law) and that failed: ") + e.what());
  }
  if (!out.plan.summary.ok())
    fail_method(std::string("phase_plane plans the task in its own time (no time law) and that plan ") +
                to_string(out.plan.summary.status) + ": " + out.plan.summary.message);
  return out;
}

/// The path's dynamics along the plan in its own time; the constraints must fix the path.
PathDynamics path_of(const Model& m, const Plan& plan, const MethodFailure& fail_method) {
  if (plan.phi.empty() || plan.phi.front().size() < m.nq)
    fail_method("phase_plane needs a path fixed by the constraints (as many rows as coordinates), and here " +
               std::to_string(plan.phi.empty() ? 0 : plan.phi.front().size()) + " rows leave " + std::to_string(m.nq) +
               " coordinates free; use slsqp or cobyla");
  PathDynamics path;
  try {
    path = path_dynamics(m, plan);
  } catch (const Error& e) {
    fail_method(e.what());
  }
  return path;
}

/// The joints' effort and speed limits; at least one must be finite.
PhasePlaneLimits joint_limits(const Model& m, const MethodFailure& fail_method) {
  PhasePlaneLimits limits{Eigen::VectorXd(m.nq), Eigen::VectorXd(m.nq)};
  bool any = false;
  for (int j = 0; j < m.nq; ++j) {
    limits.effort[j] = m.limits[static_cast<size_t>(j)].effort;
    limits.speed[j] = m.limits[static_cast<size_t>(j)].velocity;
    any = any || std::isfinite(limits.effort[j]) || std::isfinite(limits.speed[j]);
  }
  if (!any)
    fail_method("phase_plane retimes against the joints' effort and speed limits, and no joint has one (model: limits: {effort, velocity})");
  return limits;
}

/// TOPP-RA on the K parts within the variables' bounds, and refdyn's plan of its answer; while
/// that plan exceeds a limit, the limits are lowered by the excess and TOPP-RA runs again (at
/// most 8 times). Returns the run's message.
std::string retime(const PathDynamics& path, size_t K, const std::vector<size_t>& var_of, const OptimizeSetup& s,
                   const PhasePlaneLimits& limits, Evaluator& ev, std::vector<std::pair<std::string, double>>& phases,
                   double& time_optimum) {
  std::vector<double> lo(K + 1, 0.0), hi(K + 1, 0.0);
  for (size_t i = 0; i < var_of.size(); ++i) {
    lo[i + 1] = s.lower[var_of[i]] > 0 ? s.lower[var_of[i]] * s.lower[var_of[i]] : 0.0;
    hi[i + 1] = s.upper[var_of[i]] * s.upper[var_of[i]];
  }
  const double task = path.tau.back() - path.tau.front();
  {  // what the answer is judged against: the path's own time optimum (a knot at every path sample)
    const auto start = std::chrono::steady_clock::now();
    time_optimum = phase_plane_time_optimum(path, limits, *std::max_element(hi.begin(), hi.end()));
    phases.emplace_back("time_optimum", since(start));
    phases.emplace_back("topp_ra", 0.0);
  }
  // "; T* ≈ … s: the answer is +x % over it" (nothing when T* could not be estimated)
  auto versus = [&](double T) {
    if (!std::isfinite(time_optimum)) return std::string();
    return "; the path's time optimum under these limits T* ≈ " + fmt(time_optimum) + " s (a knot at every path " +
           "sample, extrapolated): this answer is " + (T >= time_optimum ? "+" : "") +
           fmt(std::round(1e4 * (T / time_optimum - 1)) / 100) + " % over it";
  };
  double mu = 1, first = 0;
  for (int round = 0;; ++round) {
    const PhasePlaneLimits L{limits.effort * mu, limits.speed * mu};
    std::vector<double> x;
    const auto topp_start = std::chrono::steady_clock::now();
    try {
      x = phase_plane_knot_law(path, static_cast<int>(K), L, lo, hi);
    } catch (const Error& e) {
      return std::string("phase plane: ") + e.what();
    }
    phases.back().second += since(topp_start);
    if (round == 0) first = knot_law_duration(x, task);
    std::vector<double> v(s.variables.size());
    for (size_t i = 0; i < var_of.size(); ++i)
      v[var_of[i]] = std::clamp(std::sqrt(x[i + 1]), s.lower[var_of[i]], s.upper[var_of[i]]);
    const OptimizeEvaluation& r = ev.at(v.data()).row;
    const std::string head = "phase plane (TOPP-RA) on " + std::to_string(K) + " parts, limits imposed at " +
                             std::to_string(path.tau.size()) + " path samples: the fastest law " + fmt(first) + " s";
    if (r.feasible)
      return head + (mu < 1 ? "; refdyn's plan of it exceeded the limits, so they were lowered to " + fmt(mu) +
                                  " of the joints' (" + std::to_string(round + 1) + " plans): " + fmt(r.objective) + " s"
                            : "; refdyn's plan of it is within the limits") +
             versus(r.objective);
    if (!r.ok) return head + "; its plan failed: " + r.reason;
    double excess = 0;
    for (size_t i = 0; i < s.constraints.size(); ++i) {
      const OptimizeConstraint& cn = s.constraints[i];
      if (cn.metric.rfind("peak_", 0) == 0) excess = std::max(excess, r.constraints[i]);
      else if (r.constraints[i] > 0)
        return head + "; the path itself leaves the range of a joint (" + cn.name + "): no time law keeps it within";
    }
    if (round == 8 || !(excess > 0))
      return head + "; refdyn's plan of it still exceeds a limit by " + fmt(100 * excess) + " % after " +
             std::to_string(round + 1) + " plans";
    mu *= 1 - excess - 1e-4;
  }
}

}  // namespace

/// method: phase_plane (optimize/phase_plane.hpp). Checks that the section asks what it answers,
/// plans the task in its own time (no law, t1 = task_duration, the initial velocity projected),
/// runs TOPP-RA on the law's knots and plans the answer. When refdyn's plan of the answer exceeds
/// a limit (between the path samples the limits were imposed at, or by the integration error
/// where s̈ jumps at a knot), the limits given to TOPP-RA are lowered by the excess and it runs
/// again (at most 8 times). Every plan is a row of the history.
std::string run_phase_plane(const ScenarioSpec& spec, const OptimizeSetup& s, Evaluator& ev, bool from_cli,
                            std::vector<std::pair<std::string, double>>& phases, double& time_optimum) {
  const SpecReader c = parameter_reader(spec);
  const MethodFailure fail_method{*spec.optimize, c, from_cli};
  check_section(spec, c, fail_method);
  const std::vector<size_t> var_of = knot_speed_variables(spec, s, c);
  const size_t K = var_of.size() + 1;

  const auto path_start = std::chrono::steady_clock::now();
  const OwnTimePlan own = plan_own_time(spec, s, c, K, fail_method);
  const Model& m = own.problem->model;
  const PathDynamics path = path_of(m, own.plan, fail_method);
  phases.emplace_back("path", since(path_start));
  const PhasePlaneLimits limits = joint_limits(m, fail_method);
  return retime(path, K, var_of, s, limits, ev, phases, time_optimum);
}

}  // namespace refdyn::optimize_detail
