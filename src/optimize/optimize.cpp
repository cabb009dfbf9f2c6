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

/// A list variable's element name "v[3]" → "v" and 2 (0-based); else "" (a scalar variable).
std::string list_element(const std::string& name, size_t& element) {
  const size_t b = name.find('[');
  if (b == std::string::npos || b == 0 || name.back() != ']' || b + 2 >= name.size()) return {};
  size_t k = 0;
  for (size_t i = b + 1; i + 1 < name.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(name[i])) || k > 1'000'000'000) return {};
    k = 10 * k + static_cast<size_t>(name[i] - '0');
  }
  if (k == 0) return {};
  element = k - 1;
  return name.substr(0, b);
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

}  // namespace

OptimizeSetup check_optimize(const ScenarioSpec& spec, const Problem& base) {
  if (!spec.optimize) throw Error(spec.file + ": optimize: missing (refdyn optimize needs an optimize: section; docs/optimize.md)");
  const OptimizeSpec& o = *spec.optimize;
  const SpecReader c = parameter_reader(spec);
  OptimizeSetup s;
  s.method = optimize_method(o.method);
  std::vector<std::string> names;
  for (const auto& p : spec.parameters) names.push_back(p.first);
  for (const auto& v : o.variables) {
    const SpecValue& at = v.value["name"];
    if (std::find(names.begin(), names.end(), v.name) == names.end())
      c.fail(at, v.key + ".name",
             "no parameter '" + v.name + "' to optimize (variables are parameters of the scenario)" + did_you_mean(v.name, names));
    if (std::find(s.variables.begin(), s.variables.end(), v.name) != s.variables.end() ||
        std::find(s.variables.begin(), s.variables.end(), v.name + "[1]") != s.variables.end())
      c.fail(at, v.key + ".name", "the parameter '" + v.name + "' is a variable twice");
    const auto list = c.lists.find(v.name);
    if (list != c.lists.end()) {  // a list parameter: one vector variable, its elements named v[1] … v[n]
      const size_t n = list->second.size();
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
        for (const Quantity& q : list->second) x0.push_back(q.value);
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
          if (!v.start) c.fail(list->second[i].where, v.key + ".start", msg + " (the parameter's value; hint: give start:)");
          c.fail(v.start.is_list() ? v.start[i] : v.start, v.key + ".start" + (v.start.is_list() ? el : ""), msg);
        }
        s.variables.push_back(v.name + "[" + std::to_string(i + 1) + "]");
        s.variable_where.push_back(at.where);
        s.lower.push_back(lo[i]);
        s.upper.push_back(hi[i]);
        s.start.push_back(x0[i]);
      }
      s.lists.push_back({v.name, s.variables.size() - n, n});
      continue;
    }
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
  check_list_gradients(s, c, o);
  const int parts = base.time_law_knots.empty() ? 0 : static_cast<int>(base.time_law_knots.size()) - 1;
  s.metric_names = metric_names(base.model, parts);
  s.maximize = o.maximize;
  s.objective = compile(c, o.objective_value, std::string("optimize.objective.") + (o.maximize ? "maximize" : "minimize"),
                        o.objective, s.metric_names, s.variables);
  s.feasible = o.feasible;
  if (o.feasible) {
    const Model& m = base.model;
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

struct Stop {};  // thrown through NLopt (as nlopt::forced_stop) to end the run

class Evaluator {
 public:
  Evaluator(const ScenarioSpec& spec, const OptimizeSetup& setup, const OptimizeOptions& options, long budget)
      : spec_(spec), s_(setup), o_(options), budget_(budget) {}

  struct Point {
    OptimizeEvaluation row;
    Eigen::RowVectorXd df;      ///< d objective / dx (gradient methods)
    Eigen::MatrixXd dg;         ///< d constraints / dx
  };

  const Point& at(const double* xp) {
    std::vector<double> x(xp, xp + s_.variables.size());
    auto it = cache_.find(x);
    if (it != cache_.end()) return points_[it->second];
    if (o_.stop && o_.stop->load()) {
      stopped = true;
      throw nlopt::forced_stop();
    }
    if (static_cast<long>(points_.size()) >= budget_) {
      budget_reached = true;
      throw nlopt::forced_stop();
    }
    points_.push_back(evaluate(x));
    cache_[x] = points_.size() - 1;
    if (o_.progress) o_.progress(points_.back().row, budget_);
    return points_.back();
  }

  /// at() with an Error kept for after NLopt (NLopt's C++ wrapper turns exceptions into a stop).
  const Point& guarded(const double* x) {
    try {
      return at(x);
    } catch (const Error& e) {
      fatal = e.what();
      throw nlopt::forced_stop();
    }
  }

  /// NLopt's objective: minimized (negated for maximize).
  double objective(const std::vector<double>& x, std::vector<double>& grad) {
    const Point& p = guarded(x.data());
    const double sign = s_.maximize ? -1 : 1;
    if (!grad.empty())
      for (size_t k = 0; k < grad.size(); ++k) grad[k] = p.row.ok ? sign * p.df(static_cast<Eigen::Index>(k)) : 0.0;
    return sign * (p.row.ok ? p.row.objective : penalty_objective());
  }

  void constraints(unsigned m, double* result, unsigned n, const double* x, double* grad) {
    const Point& p = guarded(x);
    for (unsigned i = 0; i < m; ++i) {
      result[i] = p.row.ok ? p.row.constraints[i] : 1.0;
      if (grad)
        for (unsigned k = 0; k < n; ++k) grad[i * n + k] = p.row.ok ? p.dg(i, k) : 0.0;
    }
  }

  std::vector<Point> points_;
  bool stopped = false, budget_reached = false;
  std::string fatal;

 private:
  /// A failed plan: the worst objective seen (so it is never better than a planned point).
  double penalty_objective() const {
    double worst = std::numeric_limits<double>::quiet_NaN();
    for (const auto& p : points_)
      if (p.row.ok && std::isfinite(p.row.objective))
        worst = std::isnan(worst) ? p.row.objective
                                  : (s_.maximize ? std::min(worst, p.row.objective) : std::max(worst, p.row.objective));
    return std::isnan(worst) ? 0.0 : worst;
  }

  Point evaluate(const std::vector<double>& x) {
    Point p;
    OptimizeEvaluation& r = p.row;
    r.index = static_cast<long>(points_.size());
    r.x = x;
    r.constraints.assign(s_.constraints.size(), std::numeric_limits<double>::quiet_NaN());
    r.objective = std::numeric_limits<double>::quiet_NaN();
    const auto start = std::chrono::steady_clock::now();
    const size_t nv = x.size(), nm = s_.metric_names.size();
    try {
      const auto problem = build_problem(spec_at(spec_, s_.variables, x));
      auto planner = problem->make_planner();
      const Plan plan = plan_problem(*problem, *planner);
      if (!plan.summary.ok()) {
        r.reason = std::string("plan ") + to_string(plan.summary.status) + ": " + plan.summary.message;
      } else {
        const std::vector<Metric> metrics = plan_metrics(problem->model, plan, problem->residual_from, problem->time_law_knots);
        std::vector<double> args(nm + nv, 0.0);
        for (size_t i = 0; i < nm; ++i) {
          auto it = std::find_if(metrics.begin(), metrics.end(), [&](const Metric& m) { return m.name == s_.metric_names[i]; });
          if (it != metrics.end()) args[i] = it->value;
        }
        for (size_t k = 0; k < nv; ++k) args[nm + k] = x[k];
        Eigen::MatrixXd G;  // d args / dx
        const bool grad = uses_gradients(s_.method);
        if (grad) {
          SensitivityOptions so;
          so.parameters = s_.variables;
          try {
            const PlanSensitivity sens = plan_sensitivity(*problem, plan, so);
            // Only the metrics the expressions and limits name are differentiated.
            std::vector<Metric> used;
            std::vector<size_t> rows;
            for (size_t i = 0; i < nm; ++i) {
              if (!s_.metric_used[i]) continue;
              auto it = std::find_if(metrics.begin(), metrics.end(), [&](const Metric& m) { return m.name == s_.metric_names[i]; });
              if (it == metrics.end()) continue;
              used.push_back(*it);
              rows.push_back(i);
            }
            G = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(nm + nv), static_cast<Eigen::Index>(nv));
            if (!used.empty()) {
              const Eigen::MatrixXd dm = metric_gradients(*problem, plan, sens, used);
              for (size_t k = 0; k < rows.size(); ++k)
                G.row(static_cast<Eigen::Index>(rows[k])) = dm.row(static_cast<Eigen::Index>(k));
            }
            for (size_t k = 0; k < nv; ++k) G(static_cast<Eigen::Index>(nm + k), static_cast<Eigen::Index>(k)) = 1.0;
          } catch (const Error& e) {
            // Not a property of this candidate: the method cannot be used for this scenario.
            throw Error(spec_.file + ": optimize.method: " + to_string(s_.method) +
                        " needs the plan's sensitivities: " + e.what() + " (hint: method: cobyla or bobyqa)");
          }
        }
        auto eval = [&](const Expression& e, double& v, Eigen::RowVectorXd* d) {
          std::vector<double> g(nm + nv, 0.0);
          e.evaluate(args.data(), v, d ? g.data() : nullptr, nullptr);
          if (d) *d = Eigen::Map<const Eigen::RowVectorXd>(g.data(), static_cast<Eigen::Index>(g.size())) * G;
        };
        eval(*s_.objective, r.objective, grad ? &p.df : nullptr);
        if (grad) p.dg = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(s_.constraints.size()), static_cast<Eigen::Index>(nv));
        bool feasible = std::isfinite(r.objective);
        for (size_t i = 0; i < s_.constraints.size(); ++i) {
          const OptimizeConstraint& c = s_.constraints[i];
          double v = 0;
          Eigen::RowVectorXd dv = Eigen::RowVectorXd::Zero(static_cast<Eigen::Index>(nv));
          if (c.expression >= 0) {
            eval(*s_.bounds[static_cast<size_t>(c.expression)], v, grad ? &dv : nullptr);
          } else {
            const size_t mi = static_cast<size_t>(
                std::find(s_.metric_names.begin(), s_.metric_names.end(), c.metric) - s_.metric_names.begin());
            v = args[mi];
            if (grad) dv = G.row(static_cast<Eigen::Index>(mi));
          }
          const double sg = c.upper ? 1.0 : -1.0;
          r.constraints[i] = sg * (v - c.limit) / c.scale;
          if (grad) p.dg.row(static_cast<Eigen::Index>(i)) = sg * dv / c.scale;
          feasible = feasible && r.constraints[i] <= 0;
        }
        r.ok = std::isfinite(r.objective);
        if (!r.ok) r.reason = "the objective is not finite";
        r.feasible = r.ok && feasible;
      }
    } catch (const Error& e) {
      if (std::string(e.what()).find("optimize.method:") != std::string::npos) throw;
      r.reason = e.what();
    } catch (const std::bad_alloc&) {
      r.reason = "out of memory";
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return p;
  }

  const ScenarioSpec& spec_;
  const OptimizeSetup& s_;
  const OptimizeOptions& o_;
  long budget_;
  std::map<std::vector<double>, size_t> cache_;
};

std::string trimmed(const std::string& t) {
  const size_t a = t.find_first_not_of(" \t"), b = t.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : t.substr(a, b - a + 1);
}

/// method: phase_plane (optimize/phase_plane.hpp). Checks that the section asks what it answers,
/// plans the task in its own time (no law, t1 = task_duration, the initial velocity projected),
/// runs TOPP-RA on the law's knots and plans the answer. When refdyn's plan of the answer exceeds
/// a limit (between the path samples the limits were imposed at, or by the integration error
/// where s̈ jumps at a knot), the limits given to TOPP-RA are lowered by the excess and it runs
/// again (at most 8 times). Every plan is a row of the history.
std::string run_phase_plane(const ScenarioSpec& spec, const OptimizeSetup& s, Evaluator& ev, bool from_cli,
                            std::vector<std::pair<std::string, double>>& phases) {
  auto since = [](std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const OptimizeSpec& o = *spec.optimize;
  const SpecReader c = parameter_reader(spec);
  // What is wrong with the method: located at optimize.method, or said of --method.
  auto fail_method = [&](const std::string& msg) {
    if (from_cli) throw Error("--method phase_plane: " + msg);
    c.fail(o.method_value, "optimize.method", msg);
  };
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
  const size_t K = var_of.size() + 1;
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

  // The task in its own time.
  const auto path_start = std::chrono::steady_clock::now();
  ScenarioSpec own = spec_at(spec, s.variables, s.start);
  own.time_law = SpecValue{};
  own.integrator.t1 = SpecValue::scalar(Tp.text, Tp.where);
  own.initial.project = true;
  std::unique_ptr<Problem> problem;
  Plan plan;
  try {
    problem = build_problem(own);
    auto planner = problem->make_planner();
    plan = plan_problem(*problem, *planner);
  } catch (const Error& e) {
    fail_method(std::string("phase_plane plans the task in its own time (no time law) and that failed: ") + e.what());
  }
  if (!plan.summary.ok())
    fail_method(std::string("phase_plane plans the task in its own time (no time law) and that plan ") +
                to_string(plan.summary.status) + ": " + plan.summary.message);
  const Model& m = problem->model;
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
  phases.emplace_back("path", since(path_start));
  phases.emplace_back("topp_ra", 0.0);
  PhasePlaneLimits limits{Eigen::VectorXd(m.nq), Eigen::VectorXd(m.nq)};
  bool any = false;
  for (int j = 0; j < m.nq; ++j) {
    limits.effort[j] = m.limits[static_cast<size_t>(j)].effort;
    limits.speed[j] = m.limits[static_cast<size_t>(j)].velocity;
    any = any || std::isfinite(limits.effort[j]) || std::isfinite(limits.speed[j]);
  }
  if (!any)
    fail_method("phase_plane retimes against the joints' effort and speed limits, and no joint has one (model: limits: {effort, velocity})");
  std::vector<double> lo(K + 1, 0.0), hi(K + 1, 0.0);
  for (size_t i = 0; i < var_of.size(); ++i) {
    lo[i + 1] = s.lower[var_of[i]] > 0 ? s.lower[var_of[i]] * s.lower[var_of[i]] : 0.0;
    hi[i + 1] = s.upper[var_of[i]] * s.upper[var_of[i]];
  }
  const double task = path.tau.back() - path.tau.front();
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
                            : "; refdyn's plan of it is within the limits");
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
      sum.message = run_phase_plane(spec, s, ev, !options.method.empty(), sum.phases);
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

JsonValue OptimizeSummary::to_json() const {
  JsonValue j = JsonValue::object();
  j["method"] = method;
  j["sense"] = maximize ? "maximize" : "minimize";
  j["status"] = status;
  j["message"] = message;
  j["evaluations"] = evaluations;
  JsonValue b = JsonValue::object();
  for (size_t i = 0; i < variables.size() && i < best_x.size(); ++i) b[variables[i]] = best_x[i];
  j["best"] = b;
  if (std::isfinite(best_objective)) j["objective"] = best_objective;
  else j["objective"] = nullptr;
  j["feasible"] = feasible;
  j["constraints"] = constraint_names;
  j["wall_time_s"] = wall_time;
  JsonValue ph = JsonValue::object();
  for (const auto& [name, seconds] : phases) ph[name] = seconds;
  j["phases_s"] = ph;
  return j;
}

std::string optimization_csv(const OptimizeSummary& s) {
  std::ostringstream o;
  o << "index";
  for (const auto& v : s.variables) o << "," << io::csv_text(v);
  o << ",objective";
  for (const auto& c : s.constraint_names) o << "," << io::csv_text(c);
  o << ",feasible,status,reason\n";
  for (const auto& r : s.history) {
    o << r.index;
    for (double x : r.x) o << "," << io::csv_number(x);
    o << "," << io::csv_number(r.objective);
    for (double g : r.constraints) o << "," << io::csv_number(g);
    o << "," << (r.feasible ? 1 : 0) << "," << (r.ok ? "ok" : "failed") << "," << io::csv_text(r.reason) << "\n";
  }
  return o.str();
}

std::string optimized_yaml(const std::string& text, const SpecValue& root, const std::vector<std::string>& names,
                           const std::vector<double>& values) {
  const SpecValue& params = root["parameters"];
  std::vector<size_t> line_start{0};
  for (size_t i = 0; i < text.size(); ++i)
    if (text[i] == '\n') line_start.push_back(i + 1);
  struct Edit {
    size_t at, length;
    std::string with;
  };
  std::vector<Edit> edits;
  edits.reserve(names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    size_t element = 0;
    const std::string list = list_element(names[i], element);
    const SpecValue& p = params[list.empty() ? names[i] : list];
    const SpecValue& v = list.empty() ? p : p[element];
    if (!v.is_scalar() || (!list.empty() && !p.is_list()))
      throw Error("optimized.yaml: the parameter '" + names[i] + "' was not found as a value in the parameters: section");
    const SourceLocation& w = v.where;
    if (w.line < 1 || static_cast<size_t>(w.line) > line_start.size() || w.column < 1)
      throw Error("optimized.yaml: the parameter '" + names[i] + "' has no recorded location");
    const size_t at = line_start[static_cast<size_t>(w.line - 1)] + static_cast<size_t>(w.column - 1);
    const size_t eol = std::min(text.find('\n', at), text.size());
    size_t length = 0;
    if (at < text.size() && (text[at] == '"' || text[at] == '\'') && text.find(text[at], at + 1) < eol)
      length = text.find(text[at], at + 1) + 1 - at;  // a quoted value: the quotes go too
    else if (text.compare(at, v.text.size(), v.text) == 0 && at + v.text.size() <= eol)
      length = v.text.size();
    else
      throw Error(w.file + ":" + std::to_string(w.line) + ": parameters." + names[i] +
                  ": optimized.yaml rewrites values in place, and this one is not a plain one-line value (hint: write it as a number)");
    std::string with = fmt(values[i]);
    // keep a comment where it was: pad or shrink the spaces between the value and a '#'
    size_t after = at + length, c = after;
    while (c < eol && (text[c] == ' ' || text[c] == '\t')) ++c;
    if (c < eol && text[c] == '#' && c > after) {
      const long pad = static_cast<long>(c - at) - static_cast<long>(with.size());
      with += std::string(static_cast<size_t>(std::max(1L, pad)), ' ');
      length = c - at;
    }
    edits.push_back({at, length, std::move(with)});
  }
  std::sort(edits.begin(), edits.end(), [](const Edit& x, const Edit& y) { return x.at < y.at; });
  std::string out;
  out.reserve(text.size() + 16 * edits.size());
  size_t pos = 0;
  for (const Edit& e : edits) {
    if (e.at < pos) throw Error("optimized.yaml: two variables share one value in the text");
    out.append(text, pos, e.at - pos);
    out += e.with;
    pos = e.at + e.length;
  }
  out.append(text, pos, std::string::npos);
  if (!out.empty() && out.back() != '\n') out += '\n';
  return out;
}

std::string optimized_yaml(const std::string& text, const std::vector<std::string>& names, const std::vector<double>& values) {
  return optimized_yaml(text, io::parse_yaml_tree(text, "optimized.yaml"), names, values);
}

}  // namespace refdyn
