// refdyn optimize (optimize/optimize.hpp, docs/optimize.md): NLopt around the plan pipeline.
#include "refdyn/optimize/optimize.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/io/csv.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/variants.hpp"
#include "refdyn/optimize/phase_plane.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/simulate/metrics.hpp"
#include "refdyn/symbolic/sensitivity.hpp"

#include "evaluator.hpp"

#include <nlopt.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <regex>
#include <sstream>

namespace refdyn {

using optimize_detail::Evaluator;
using optimize_detail::list_element;
using optimize_detail::Stop;
using optimize_detail::run_phase_plane;

namespace {
const std::vector<std::string> kMethods{"slsqp", "mma", "cobyla", "bobyqa", "phase_plane"};
}

const char* to_string(OptimizeMethod m) {
  switch (m) {
    case OptimizeMethod::Slsqp: return "slsqp";
    case OptimizeMethod::Mma: return "mma";
    case OptimizeMethod::Cobyla: return "cobyla";
    case OptimizeMethod::Bobyqa: return "bobyqa";
    case OptimizeMethod::PhasePlane: return "phase_plane";
  }
  return "?";
}

OptimizeMethod optimize_method(const std::string& name) {
  for (size_t i = 0; i < kMethods.size(); ++i)
    if (kMethods[i] == name) return static_cast<OptimizeMethod>(i);
  throw Error("unknown optimization method '" + name + "' (expected one of slsqp, mma, cobyla, bobyqa, phase_plane)" +
              did_you_mean(name, kMethods));
}

namespace {

/// An expression of (metric names…, variables…) with the scenario's other parameters as constants.
std::shared_ptr<const Expression> compile(const SpecReader& c, const SpecValue& at, const std::string& key,
                                          const std::string& text, const std::vector<std::string>& metrics,
                                          const std::vector<std::string>& variables) {
  std::vector<std::string> vars = metrics;
  for (const auto& v : variables) {  // a list's elements v[i] are no names of the language: placeholders
    const size_t b = v.find('[');
    vars.push_back(b == std::string::npos ? v : "__" + v.substr(0, b) + "_" + v.substr(b + 1, v.size() - b - 2));
  }
  std::map<std::string, double> params = c.params;
  for (const auto& v : variables) params.erase(v);
  for (const auto& m : metrics) params.erase(m);
  try {
    return std::make_shared<const Expression>(text, vars, params, 1);
  } catch (const Error& e) {
    std::string msg = e.what();
    // Name the likely intended metric.
    static const std::regex ident(R"(([A-Za-z_][A-Za-z_0-9]*(\s*\([^()]*\))?))");
    for (std::sregex_iterator it(text.begin(), text.end(), ident), end; it != end; ++it) {
      std::string w = (*it)[1].str();
      w.erase(std::remove_if(w.begin(), w.end(), [](unsigned char ch) { return std::isspace(ch); }), w.end());
      if (w.find('(') == std::string::npos) continue;
      if (std::find(metrics.begin(), metrics.end(), w) == metrics.end()) {
        msg = "unknown metric '" + w + "'" + did_you_mean(w, metrics) + " (metrics: docs/optimize.md)";
        break;
      }
    }
    c.fail(at, key, msg);
  }
}


/// slsqp and mma differentiate the plan by the parameters' symbols, and a list parameter's
/// elements are numbers to the symbolic layer: refused where the list variable is named.
void check_list_gradients(const OptimizeSetup& s, const SpecReader& c, const OptimizeSpec& o) {
  if (!uses_gradients(s.method) || s.lists.empty()) return;
  for (const auto& v : o.variables)
    if (v.name == s.lists.front().name)
      c.fail(v.value["name"], v.key + ".name",
             std::string(to_string(s.method)) + " needs the plan's sensitivities, and the elements of the list parameter '" + v.name +
                 "' have none (they are numbers to the symbolic layer); use method: phase_plane (knot speeds), cobyla or bobyqa");
}

/// A list parameter as a variable: one vector variable, its elements named v[1] … v[n].
void add_list_variable(const OptimizeVariableSpec& v, const std::vector<Quantity>& values, const SpecReader& c,
                       OptimizeSetup& s) {
  const SpecValue& at = v.value["name"];
  const size_t n = values.size();
  // lower, upper, start: one number for every element, or a list of n numbers
  auto numbers = [&](const SpecValue& b, const std::string& k) {
    std::vector<double> out;
    if (b.is_list()) {
      if (b.size() != n)
        c.fail(b, k,
               "expected one number for every element or a list of " + std::to_string(n) + " (the length of '" + v.name +
                   "'), got a list of " + std::to_string(b.size()) + " (hint: write one number for all)");
      for (size_t i = 0; i < n; ++i) out.push_back(c.number(b[i], k + "[" + std::to_string(i) + "]"));
    } else {
      out.assign(n, c.number(b, k));
    }
    return out;
  };
  const std::vector<double> lo = numbers(v.lower, v.key + ".lower"), hi = numbers(v.upper, v.key + ".upper");
  std::vector<double> x0;
  if (v.start) x0 = numbers(v.start, v.key + ".start");
  else
    for (const Quantity& q : values) x0.push_back(q.value);
  for (size_t i = 0; i < n; ++i) {
    const std::string el = "[" + std::to_string(i) + "]";
    const SpecValue& lv = v.lower.is_list() ? v.lower[i] : v.lower;
    if (lo[i] > hi[i])
      c.fail(lv, v.key + ".lower" + (v.lower.is_list() || v.upper.is_list() ? el : ""),
             "lower = " + fmt(lo[i]) + " is above upper = " + fmt(hi[i]) +
                 (v.lower.is_list() || v.upper.is_list() ? " (element " + std::to_string(i) + " of '" + v.name + "')" : ""));
    if (x0[i] < lo[i] || x0[i] > hi[i]) {
      const std::string msg = "start = " + fmt(x0[i]) + " (element " + std::to_string(i) + " of '" + v.name +
                              "') is outside [" + fmt(lo[i]) + ", " + fmt(hi[i]) + "]";
      if (!v.start) c.fail(values[i].where, v.key + ".start", msg + " (the parameter's value; hint: give start:)");
      c.fail(v.start.is_list() ? v.start[i] : v.start, v.key + ".start" + (v.start.is_list() ? el : ""), msg);
    }
    s.variables.push_back(v.name + "[" + std::to_string(i + 1) + "]");
    s.variable_where.push_back(at.where);
    s.lower.push_back(lo[i]);
    s.upper.push_back(hi[i]);
    s.start.push_back(x0[i]);
  }
  s.lists.push_back({v.name, s.variables.size() - n, n});
}

/// A parameter with one value as a variable: its lower, upper and start single numbers.
void add_scalar_variable(const OptimizeVariableSpec& v, const SpecReader& c, OptimizeSetup& s) {
  const SpecValue& at = v.value["name"];
  for (const auto* b : {&v.lower, &v.upper, &v.start})
    if (b->is_list())
      c.fail(*b, v.key, "'" + v.name + "' is a parameter with one value: its lower, upper and start are single numbers, got a list");
  const double lo = c.number(v.lower, v.key + ".lower"), hi = c.number(v.upper, v.key + ".upper");
  if (lo > hi) c.fail(v.lower, v.key + ".lower", "lower = " + fmt(lo) + " is above upper = " + fmt(hi));
  double x0 = c.params.at(v.name);
  if (v.start) x0 = c.number(v.start, v.key + ".start");
  if (x0 < lo || x0 > hi)
    c.fail(v.start ? v.start : v.value, v.key + ".start",
           "start = " + fmt(x0) + " is outside [" + fmt(lo) + ", " + fmt(hi) + "]" +
               (v.start ? "" : " (the parameter's value; hint: give start:)"));
  s.variables.push_back(v.name);
  s.variable_where.push_back(at.where);
  s.lower.push_back(lo);
  s.upper.push_back(hi);
  s.start.push_back(x0);
}

/// The variables: parameters of the scenario, each named once.
void add_variables(const ScenarioSpec& spec, const SpecReader& c, OptimizeSetup& s) {
  std::vector<std::string> names;
  for (const auto& p : spec.parameters) names.push_back(p.first);
  for (const auto& v : spec.optimize->variables) {
    const SpecValue& at = v.value["name"];
    if (std::find(names.begin(), names.end(), v.name) == names.end())
      c.fail(at, v.key + ".name",
             "no parameter '" + v.name + "' to optimize (variables are parameters of the scenario)" + did_you_mean(v.name, names));
    if (std::find(s.variables.begin(), s.variables.end(), v.name) != s.variables.end() ||
        std::find(s.variables.begin(), s.variables.end(), v.name + "[1]") != s.variables.end())
      c.fail(at, v.key + ".name", "the parameter '" + v.name + "' is a variable twice");
    const auto list = c.lists.find(v.name);
    if (list != c.lists.end()) add_list_variable(v, list->second, c, s);
    else add_scalar_variable(v, c, s);
  }
}

/// constraints: {feasible: true}: the joints' speed, effort and range limits as constraints.
void add_limit_constraints(const Model& m, int parts, OptimizeSetup& s) {
  for (int j = 0; j < m.nq; ++j) {
    const JointLimits& l = m.limits[static_cast<size_t>(j)];
    const std::string& jn = m.joint_name[static_cast<size_t>(j)];
    auto add = [&](const std::string& what, const std::string& metric, double limit, bool upper) {
      if (!std::isfinite(limit)) return;
      s.constraints.push_back({what + "(" + jn + ")", metric + "(" + jn + ")", -1, limit,
                               limit != 0 ? std::abs(limit) : 1.0, upper});
    };
    if (parts == 0) {
      add("velocity", "peak_speed", l.velocity, true);
      add("effort", "peak_effort", l.effort, true);
    } else {  // under a time law: one constraint per part (the TOPP-RA constraints), not one maximum
      for (int i = 1; i <= parts; ++i) add("velocity_part" + std::to_string(i), "peak_speed_part" + std::to_string(i), l.velocity, true);
      for (int i = 1; i <= parts; ++i) add("effort_part" + std::to_string(i), "peak_effort_part" + std::to_string(i), l.effort, true);
    }
    add("upper", "q_max", l.upper, true);
    add("lower", "q_min", l.lower, false);
  }
}

/// The section's bounds: each expression compiled, its lower and upper limits as constraints.
void add_bounds(const SpecReader& c, const OptimizeSpec& o, OptimizeSetup& s) {
  for (size_t i = 0; i < o.bounds.size(); ++i) {
    const OptimizeBoundSpec& b = o.bounds[i];
    s.bounds.push_back(compile(c, b.value["expression"], b.key + ".expression", b.expression, s.metric_names, s.variables));
    double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
    if (b.lower) lo = c.number(b.lower, b.key + ".lower");
    if (b.upper) hi = c.number(b.upper, b.key + ".upper");
    if (lo > hi) c.fail(b.lower, b.key + ".lower", "lower = " + fmt(lo) + " is above upper = " + fmt(hi));
    const std::string name = "bounds[" + std::to_string(i) + "]";
    if (b.lower) s.constraints.push_back({name + ".lower", "", static_cast<int>(i), lo, lo != 0 ? std::abs(lo) : 1.0, false});
    if (b.upper) s.constraints.push_back({name + ".upper", "", static_cast<int>(i), hi, hi != 0 ? std::abs(hi) : 1.0, true});
  }
}

/// The metrics the objective, the bounds and the limit constraints use (only those are computed).
void mark_used_metrics(OptimizeSetup& s) {
  s.metric_used.assign(s.metric_names.size(), false);
  auto mark = [&](const Expression& e) {
    for (int i : e.referenced_variables())
      if (static_cast<size_t>(i) < s.metric_names.size()) s.metric_used[static_cast<size_t>(i)] = true;
  };
  mark(*s.objective);
  for (const auto& b : s.bounds) mark(*b);
  for (const auto& c : s.constraints)
    if (c.expression < 0)
      s.metric_used[static_cast<size_t>(std::find(s.metric_names.begin(), s.metric_names.end(), c.metric) -
                                        s.metric_names.begin())] = true;
}

/// The stopping criteria: relative tolerances on x and f, the budget of plan evaluations.
void read_stopping_criteria(const SpecReader& c, const OptimizeSpec& o, OptimizeSetup& s) {
  if (o.tolerance_x) {
    s.xtol = c.number(o.tolerance_x, "optimize.tolerance.x");
    if (!(s.xtol >= 0)) c.fail(o.tolerance_x, "optimize.tolerance.x", "expected a relative tolerance ≥ 0, got " + fmt(s.xtol));
  }
  if (o.tolerance_f) {
    s.ftol = c.number(o.tolerance_f, "optimize.tolerance.f");
    if (!(s.ftol >= 0)) c.fail(o.tolerance_f, "optimize.tolerance.f", "expected a relative tolerance ≥ 0, got " + fmt(s.ftol));
  }
  if (o.budget) {
    const double b = c.number(o.budget, "optimize.budget");
    if (!(b >= 1) || b != std::floor(b) || b > 1e7)
      c.fail(o.budget, "optimize.budget", "expected a whole number of plan evaluations > 0, got " + fmt(b));
    s.budget = static_cast<long>(b);
  }
}

}  // namespace

OptimizeSetup check_optimize(const ScenarioSpec& spec, const Problem& base) {
  if (!spec.optimize) throw Error(spec.file + ": optimize: missing (refdyn optimize needs an optimize: section; docs/optimize.md)");
  const OptimizeSpec& o = *spec.optimize;
  const SpecReader c = parameter_reader(spec);
  OptimizeSetup s;
  s.method = optimize_method(o.method);
  add_variables(spec, c, s);
  check_list_gradients(s, c, o);
  const int parts = base.time_law_knots.empty() ? 0 : static_cast<int>(base.time_law_knots.size()) - 1;
  s.metric_names = metric_names(base.model, parts);
  s.maximize = o.maximize;
  s.objective = compile(c, o.objective_value, std::string("optimize.objective.") + (o.maximize ? "maximize" : "minimize"),
                        o.objective, s.metric_names, s.variables);
  s.feasible = o.feasible;
  if (o.feasible) add_limit_constraints(base.model, parts, s);
  add_bounds(c, o, s);
  mark_used_metrics(s);
  read_stopping_criteria(c, o, s);
  return s;
}

ScenarioSpec spec_at(const ScenarioSpec& spec, const std::vector<std::string>& variables, const std::vector<double>& x) {
  io::Variant v;
  v.name = "candidate";
  std::map<std::string, std::vector<double>> lists;
  for (size_t i = 0; i < variables.size(); ++i) {
    size_t element = 0;
    const std::string base = list_element(variables[i], element);
    if (base.empty()) {
      v.values.emplace_back(variables[i], x[i]);
      continue;
    }
    auto it = std::find_if(spec.parameters.begin(), spec.parameters.end(), [&](const auto& p) { return p.first == base; });
    if (it == spec.parameters.end() || !it->second.is_list() || element >= it->second.size())
      throw Error("optimize: no list parameter element '" + variables[i] + "' to set");
    std::vector<double>& l = lists[base];
    if (l.empty()) l.assign(it->second.size(), std::numeric_limits<double>::quiet_NaN());
    l[element] = x[i];
  }
  ScenarioSpec s = io::variant_spec(spec, v);
  for (auto& [name, values] : lists) {
    if (std::any_of(values.begin(), values.end(), [](double e) { return std::isnan(e); })) {
      // the elements not set keep their written values
      const SpecReader c = parameter_reader(spec);
      const std::vector<Quantity>& written = c.lists.at(name);
      for (size_t k = 0; k < values.size(); ++k)
        if (std::isnan(values[k])) values[k] = written[k].value;
    }
    s.list_values[name] = std::move(values);
  }
  s.optimize.reset();
  return s;
}

namespace {

const char* result_name(nlopt::result r) {
  switch (r) {
    case nlopt::SUCCESS: return "success";
    case nlopt::STOPVAL_REACHED: return "success";
    case nlopt::FTOL_REACHED: return "ftol_reached";
    case nlopt::XTOL_REACHED: return "xtol_reached";
    case nlopt::MAXEVAL_REACHED: return "budget";
    case nlopt::MAXTIME_REACHED: return "budget";
    case nlopt::ROUNDOFF_LIMITED: return "roundoff_limited";
    case nlopt::FORCED_STOP: return "stopped";
    default: return "failure";
  }
}

/// The NLopt optimizer of the method, bounds, tolerances, budget, objective and constraints.
nlopt::opt make_nlopt(const OptimizeSetup& s, unsigned n, unsigned m, Evaluator& ev) {
  nlopt::algorithm alg = nlopt::LD_SLSQP;
  switch (s.method) {
    case OptimizeMethod::Slsqp: alg = nlopt::LD_SLSQP; break;
    case OptimizeMethod::Mma: alg = nlopt::LD_MMA; break;
    case OptimizeMethod::Cobyla: alg = nlopt::LN_COBYLA; break;
    case OptimizeMethod::Bobyqa: alg = m ? nlopt::AUGLAG : nlopt::LN_BOBYQA; break;
    case OptimizeMethod::PhasePlane: break;  // not NLopt (run_phase_plane)
  }
  nlopt::opt opt(alg, n);
  if (alg == nlopt::AUGLAG) {  // BOBYQA has no nonlinear constraints: the augmented Lagrangian around it
    nlopt::opt local(nlopt::LN_BOBYQA, n);
    local.set_xtol_rel(s.xtol);
    local.set_ftol_rel(s.ftol);
    opt.set_local_optimizer(local);
  }
  opt.set_lower_bounds(s.lower);
  opt.set_upper_bounds(s.upper);
  opt.set_xtol_rel(s.xtol);
  opt.set_ftol_rel(s.ftol);
  opt.set_maxeval(static_cast<int>(std::min<long>(4 * s.budget + 10, 1'000'000'000)));
  opt.set_min_objective(
      [](const std::vector<double>& x, std::vector<double>& grad, void* data) {
        return static_cast<Evaluator*>(data)->objective(x, grad);
      },
      &ev);
  if (m)
    opt.add_inequality_mconstraint(
        [](unsigned mm, double* result, unsigned nn, const double* x, double* grad, void* data) {
          static_cast<Evaluator*>(data)->constraints(mm, result, nn, x, grad);
        },
        &ev, std::vector<double>(m, 0.0));
  return opt;
}

}  // namespace

OptimizeResult optimize_scenario(const ScenarioSpec& spec, const OptimizeOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizeResult out;
  {
    const auto base = build_problem(spec_at(spec, {}, {}));
    out.setup = check_optimize(spec, *base);
  }
  const double setup_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!options.method.empty()) try {
      out.setup.method = optimize_method(options.method);
    } catch (const Error& e) {
      throw Error(std::string("--method: ") + e.what());
    }
  OptimizeSetup& s = out.setup;
  if (!options.method.empty()) check_list_gradients(s, parameter_reader(spec), *spec.optimize);
  if (options.budget > 0) s.budget = options.budget;
  const unsigned n = static_cast<unsigned>(s.variables.size());
  const unsigned m = static_cast<unsigned>(s.constraints.size());
  Evaluator ev(spec, s, options, s.budget);


  OptimizeSummary& sum = out.summary;
  sum.method = to_string(s.method);
  sum.maximize = s.maximize;
  sum.variables = s.variables;
  for (const auto& c : s.constraints) sum.constraint_names.push_back(c.name);
  nlopt::result res = nlopt::FAILURE;
  sum.phases.emplace_back("setup", setup_time);
  const auto search_start = std::chrono::steady_clock::now();
  try {
    if (s.method == OptimizeMethod::PhasePlane) {
      sum.message = run_phase_plane(spec, s, ev, !options.method.empty(), sum.phases, sum.time_optimum);
      res = nlopt::SUCCESS;  // failure when no plan of it is feasible (below)
    } else {
      nlopt::opt opt = make_nlopt(s, n, m, ev);
      std::vector<double> x = s.start;
      double f = 0;
      res = opt.optimize(x, f);
      sum.message = "NLopt: " + std::string(result_name(res));
    }
  } catch (const nlopt::forced_stop&) {
    res = nlopt::FORCED_STOP;
  } catch (const nlopt::roundoff_limited&) {
    res = nlopt::ROUNDOFF_LIMITED;
    sum.message = "NLopt: roundoff limited the progress";
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    res = nlopt::FAILURE;
    sum.message = std::string("NLopt: ") + e.what();
  }
  if (!ev.fatal.empty()) throw Error(ev.fatal);
  {
    double plans = 0;
    for (const auto& p : ev.points_) plans += p.row.seconds;
    sum.phases.emplace_back("plans", plans);
    sum.phases.emplace_back("optimizer", std::chrono::duration<double>(std::chrono::steady_clock::now() - search_start).count());
  }
  sum.status = result_name(res);
  if (ev.stopped) {
    sum.status = "stopped";
    sum.stopped = true;
    sum.message = "interrupted";
  } else if (ev.budget_reached) {
    sum.status = "budget";
    sum.message = "the budget of " + std::to_string(s.budget) + " plan evaluations is spent";
  }
  for (auto& p : ev.points_) sum.history.push_back(p.row);
  sum.evaluations = static_cast<long>(sum.history.size());
  // The best feasible point; without one, the planned point with the least violation.
  const OptimizeEvaluation* best = nullptr;
  for (const auto& r : sum.history) {
    if (!r.feasible) continue;
    if (!best || (s.maximize ? r.objective > best->objective : r.objective < best->objective)) best = &r;
  }
  sum.feasible = best != nullptr;
  if (s.method == OptimizeMethod::PhasePlane && !sum.feasible && sum.status == "success") sum.status = "failure";
  if (!best) {
    double least = std::numeric_limits<double>::infinity();
    for (const auto& r : sum.history) {
      if (!r.ok) continue;
      double v = 0;
      for (double g : r.constraints) v = std::max(v, g);
      if (v < least) least = v, best = &r;
    }
  }
  if (best) {
    sum.best_x = best->x;
    sum.best_objective = best->objective;
  } else {
    sum.best_x = s.start;
    sum.best_objective = std::numeric_limits<double>::quiet_NaN();
  }
  out.best_spec = spec_at(spec, s.variables, sum.best_x);
  sum.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace refdyn
