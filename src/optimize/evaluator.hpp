#pragma once
// Private to src/optimize: the evaluator that plans a candidate and caches it (optimize.cpp's NLopt
// driver and phase_plane_run.cpp use it), and the helpers they share.
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
#include <string>
#include <vector>

namespace refdyn::optimize_detail {

/// A list variable's element name "v[3]" → "v" and 2 (0-based); else "" (a scalar variable).
inline std::string list_element(const std::string& name, size_t& element) {
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

inline std::string trimmed(const std::string& t) {
  const size_t a = t.find_first_not_of(" \t"), b = t.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : t.substr(a, b - a + 1);
}

/// method: phase_plane (phase_plane_run.cpp).
std::string run_phase_plane(const ScenarioSpec& spec, const OptimizeSetup& s, Evaluator& ev, bool from_cli,
                            std::vector<std::pair<std::string, double>>& phases, double& time_optimum);

}  // namespace refdyn::optimize_detail
