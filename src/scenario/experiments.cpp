// build_problem, the experiments section: sweeps, grids and Monte Carlo samples → Experiments.
#include "refdyn/scenario/problem.hpp"

#include "build.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <random>
#include <map>
#include <set>

namespace refdyn::build {

namespace {

/// Portable random numbers for monte_carlo experiments (docs/scenario.md, "experiments"): the
/// engine std::mt19937_64 is specified exactly by the standard, its distributions are not, so
/// the distributions are ours. u = (top 53 bits of the next output) · 2^−53, in [0, 1).
double uniform01(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }

/// Box–Muller with two uniforms u1, u2 (drawn in that order); 1 − u1 is in (0, 1], so the
/// logarithm is finite. The second value of the pair is not used: each normal takes two draws.
double standard_normal(std::mt19937_64& g) {
  const double u1 = uniform01(g);
  const double u2 = uniform01(g);
  return std::sqrt(-2.0 * std::log(1.0 - u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

/// x + y·z with the product rounded on its own: compilers may contract x + y*z into a fused
/// multiply-add (GCC does with -march=native, even in ISO mode), which rounds once and would
/// make the drawn values depend on the machine. The volatile keeps them the same everywhere.
double add_product(double x, double y, double z) {
  volatile double p = y * z;
  return x + p;
}


/// A Monte Carlo seed: an unsigned 64-bit integer written in digits (no expression: a double
/// would round seeds above 2^53).
std::uint64_t read_seed(const SpecReader& c, const SpecValue& v, const std::string& key) {
  std::uint64_t seed = 0;
  const std::string& t = v.text;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), seed);
  if (!v.is_scalar() || t.empty() || r.ec != std::errc() || r.ptr != t.data() + t.size())
    c.fail(v, key, "expected a whole number 0 to 18446744073709551615 written in digits, got " + v.describe());
  return seed;
}

ControllerFactory read_controller(const SpecReader& c, const EntrySpec& e, const Model& m, const Actuation& a) {
  return build_entry(c, controller_kinds(), e, "type", [&](const ControllerKind& k) {
    return k.build(EntryArgs{c, e, m, &a});
  });
}

/// `actuators: [joint, …]` (default: every joint) and the plant's material rows, checked at the
/// initial state (make_actuation): Problem::material and Problem::actuation.
void build_plant(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  std::vector<int> actuated;
  if (const SpecValue& a = spec.actuators) {
    if (!a.is_list()) c.fail(a, "actuators", "expected a list of joints with a motor, got " + a.describe());
    for (size_t i = 0; i < a.size(); ++i) {
      const std::string key = "actuators[" + std::to_string(i) + "]";
      const std::string j = c.joint(a[i], key, m);
      const int idx = static_cast<int>(std::find(m.joint_name.begin(), m.joint_name.end(), j) - m.joint_name.begin());
      if (std::find(actuated.begin(), actuated.end(), idx) != actuated.end())
        c.fail(a[i], key, "the joint '" + j + "' is listed twice");
      actuated.push_back(idx);
    }
    if (actuated.empty() && (!spec.experiments.empty() || spec.controller))
      c.fail(a, "actuators", "an empty list, but the scenario tracks experiments: list the joints that have a motor");
  } else {
    for (int i = 0; i < m.nv; ++i) actuated.push_back(i);
  }
  auto material = std::make_shared<ConstraintSet>();
  for (const ConstraintPtr& k : s.constraints.constraints())
    if (k->origin == ConstraintOrigin::Material && k->order() <= 1) material->add(k);
  if (material->rows() > 0) s.material = material;
  s.actuation = Actuation::full(m);
  s.actuation.actuated = actuated;
  std::sort(s.actuation.actuated.begin(), s.actuation.actuated.end());
  if (spec.experiments.empty() && !spec.controller) return;  // no closed loop: nothing to check
  const ReferenceDynamicsOptions& o = s.options;
  try {
    s.actuation = make_actuation(m, s.material, actuated, s.integrator.t0, s.q0, s.qd0, o.alpha, o.beta,
                                 o.beta_first_order, o.max_condition);
  } catch (const Error& e) {
    const SpecValue& at = spec.actuators ? spec.actuators : spec.controller ? spec.controller->fields : spec.experiments_value;
    c.fail(at, "actuators", std::string(e.what()));
  }
}


/// An experiment's name is part of a file name (track_<name>.csv): letters, digits and . _ - + =
/// only, not starting with a dot.
void check_file_name(const SpecReader& c, const SpecValue& at, const std::string& key, const std::string& name) {
  check_output_name(c, at, key, name, "experiment");
}


/// One parameter of an experiment: a sweep's, one of a grid's, or a Monte Carlo distribution.
struct ExperimentAxis {
  std::string name, key;
  const SpecValue* at;
  std::vector<double> values;  // sweep, grid
  bool normal = false;         // Monte Carlo: normal(a = mean, b = std) or uniform(a = low, b = high)
  double a = 0, b = 0;
};

/// The experiment's own parameters, checked and read (values, distributions; `seed` for Monte Carlo).
std::vector<ExperimentAxis> experiment_axes(const SpecReader& c, const ExperimentSpec& e, std::uint64_t& seed) {
  const std::string& k = e.key;
  std::vector<ExperimentAxis> axes;
  std::string what = "sweep";
  if (!e.sweep_parameter.empty()) axes.push_back({e.sweep_parameter, k + ".sweep." + e.sweep_parameter, &e.sweep, {}});
  for (const auto& [name, values] : e.grid) {
    what = "grid";
    axes.push_back({name, k + ".grid." + name, &e.grid_value[name], {}});
  }
  if (e.monte_carlo)
    for (const DistributionSpec& d : e.monte_carlo->distributions) {
      what = "Monte Carlo";
      axes.push_back({d.parameter, k + ".monte_carlo.distributions." + d.parameter, &d.value, {}});
    }
  for (const ExperimentAxis& a : axes) {
    if (c.params.count(a.name) || a.name == "pi" || a.name == "e" || a.name == "t")
      c.fail(*a.at, a.key,
             "the " + what + " parameter '" + a.name + "' has the name of a parameter (or a constant); choose another name");
    if (e.monte_carlo && a.name == "sample")
      c.fail(*a.at, a.key, "'sample' is reserved in a Monte Carlo experiment ({sample} in the name is the sample index); "
                           "choose another name");
  }
  if (!e.sweep_parameter.empty())
    for (const SpecValue& v : e.sweep_values) axes[0].values.push_back(c.number(v, axes[0].key));
  for (size_t i = 0; i < e.grid.size(); ++i)
    for (const SpecValue& v : e.grid[i].second) axes[i].values.push_back(c.number(v, axes[i].key));
  if (e.monte_carlo) {
    seed = read_seed(c, e.monte_carlo->seed, k + ".monte_carlo.seed");
    for (size_t i = 0; i < axes.size(); ++i) {
      const DistributionSpec& d = e.monte_carlo->distributions[i];
      const std::string dk = axes[i].key + "." + d.kind;
      ExperimentAxis& a = axes[i];
      a.normal = d.kind == "normal";
      a.a = c.number(d.a, dk + (a.normal ? ".mean" : ".low"));
      a.b = c.number(d.b, dk + (a.normal ? ".std" : ".high"));
      if (a.normal && !(a.b >= 0))
        c.fail(d.b, dk + ".std", "expected a standard deviation >= 0, got " + fmt(a.b));
      if (!a.normal && !(a.a <= a.b))
        c.fail(d.value[d.kind], dk, "expected low <= high, got low = " + fmt(a.a) + " > high = " + fmt(a.b));
      if (!a.normal && !std::isfinite(a.b - a.a))
        c.fail(d.value[d.kind], dk, "high - low = " + fmt(a.b - a.a) + " is not a finite number");
    }
  }
  return axes;
}

/// One entry of `experiments:` expanded into its runs (Problem::experiments).
void build_experiment(const SpecReader& c, const ScenarioSpec& spec, const ExperimentSpec& e,
                      const ControllerFactory& top_controller, const std::string& top_type,
                      std::set<std::string>& experiment_names, Problem& s) {
  const Model& m = s.model;
  const std::string& k = e.key;
  if (!spec.controller && !e.controller)
    c.fail(e.value, "controller",
           "experiments need a controller (add a 'controller:' section, at the top level or in the experiment)");
  // The experiment's own parameters, in the order written: the sweep's, the grid's (first
  // slowest) or the Monte Carlo distributions (drawn per sample in this order).
  std::uint64_t seed = 0;
  std::vector<ExperimentAxis> axes = experiment_axes(c, e, seed);
  std::mt19937_64 generator;
  if (e.monte_carlo) generator.seed(seed);
  // Counted and checked against limits.max_runs above.
  const long runs = static_cast<long>(experiment_runs(c, e));
  const size_t width = std::to_string(runs - 1).size();
  const auto padded = [width](long i) {
    const std::string d = std::to_string(i);
    return std::string(width - std::min(width, d.size()), '0') + d;
  };
  const std::string index = k.substr(k.find('[') + 1, k.find(']') - k.find('[') - 1);
  std::string available;  // the placeholders this experiment's names may use
  for (const ExperimentAxis& a : axes) available += (available.empty() ? "{" : ", {") + a.name + "}";
  if (e.monte_carlo) available += ", {sample}";
  const std::string placeholders = e.monte_carlo ? "{sample}" : available.empty() ? "{param}" : available;
  std::vector<double> values(axes.size());
  for (long run = 0; run < runs; ++run) {
    if (e.monte_carlo) {
      for (size_t i = 0; i < axes.size(); ++i) {
        const ExperimentAxis& a = axes[i];
        values[i] = a.normal ? add_product(a.a, a.b, standard_normal(generator))
                             : add_product(a.a, a.b - a.a, uniform01(generator));
        if (!std::isfinite(values[i]))
          c.fail(*a.at, a.key, "sample " + std::to_string(run) + " drew " + fmt(values[i]) + ", not a finite number");
      }
    } else {
      long rest = run;  // row-major: the last parameter varies fastest
      for (size_t i = axes.size(); i-- > 0;) {
        const long n = static_cast<long>(axes[i].values.size());
        values[i] = axes[i].values[rest % n];
        rest /= n;
      }
    }
    SpecReader ce = c;  // the run's parameters are visible in its values
    auto exp = std::make_unique<Experiment>();
    std::string name = e.named ? e.name : runs == 1 ? "run" + index : "run" + index + "_" + padded(run);
    for (size_t i = 0; i < axes.size(); ++i) {
      ce.params[axes[i].name] = values[i];
      exp->sweep.emplace_back(axes[i].name, values[i]);
      if (e.named) name = substitute(name, axes[i].name, values[i]);
    }
    if (e.monte_carlo) {
      exp->sample = run;
      exp->seed = seed;
      if (e.named)
        for (size_t pos; (pos = name.find("{sample}")) != std::string::npos;) name.replace(pos, 8, padded(run));
    }
    if (const size_t open = name.find('{'); open != std::string::npos && name.find('}', open) != std::string::npos)
      c.fail(e.value["name"], k + ".name",
             "the name has the placeholder '" + name.substr(open, name.find('}', open) - open + 1) +
                 "', which is not a parameter of this experiment (" +
                 (available.empty() ? std::string("it has none") : "it has " + available) + ")");
    exp->name = std::move(name);
    check_file_name(c, e.value["name"] ? e.value["name"] : e.value, k + ".name", exp->name);
    if (!experiment_names.insert(exp->name).second)
      c.fail(e.value["name"] ? e.value["name"] : e.value, k + ".name",
             "duplicate experiment name '" + exp->name + "' (use " + placeholders + " in the name)");
    exp->q0 = s.q0;
    exp->qd0 = Eigen::VectorXd::Zero(m.nq);
    if (e.initial_q) {
      const Eigen::VectorXd given = ce.joint_vector(e.initial_q, k + ".initial.q", m, false, std::nan(""));
      for (int j = 0; j < m.nq; ++j)
        if (!std::isnan(given[j])) exp->q0[j] = given[j];
    }
    if (e.initial_qd) exp->qd0 = ce.joint_vector(e.initial_qd, k + ".initial.qd", m, false, 0.0);
    if (const auto* plant = e.plant_forces ? &*e.plant_forces : spec.plant_forces ? &*spec.plant_forces : nullptr) {
      read_forces(ce, *plant, m, exp->plant_forces);
      check_force_capabilities(ce, *plant, exp->plant_forces, s.integrator.method == IntegratorMethod::BDF, false);
    }
    if (e.controller) {
      exp->make_controller = read_controller(ce, *e.controller, m, s.actuation);
      exp->controller_type = e.controller->kind;
    } else {
      exp->make_controller = top_controller;
      exp->controller_type = top_type;
    }
    s.experiments.push_back(std::move(exp));
  }
}

}  // namespace

void build_experiments(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  // Tracking. Gains are numbers or expressions in the parameters (and, inside an experiment,
  // its sweep parameter).
  build_plant(c, spec, s);
  ControllerFactory top_controller;
  std::string top_type;
  if (spec.controller) {
    top_controller = read_controller(c, *spec.controller, m, s.actuation);
    top_type = spec.controller->kind;
  }
  if (spec.effort_limit) {
    s.effort_limit = c.joint_vector(spec.effort_limit, "effort_limit", m, false, std::numeric_limits<double>::infinity());
    for (int i = 0; i < m.nq; ++i)
      if (!(s.effort_limit[i] >= 0))
        c.fail(spec.effort_limit, "effort_limit." + m.joint_name[i],
               "expected a limit >= 0 [N m or N], got " + fmt(s.effort_limit[i]));
  }
  std::set<std::string> experiment_names;
  for (const ExperimentSpec& e : spec.experiments)
    build_experiment(c, spec, e, top_controller, top_type, experiment_names, s);
}

}  // namespace refdyn::build
