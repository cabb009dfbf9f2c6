// build_problem: a ScenarioSpec (as written) becomes a checked Problem. The section builders
// are here (constraints and forces, jerk scope, reference options, integrator, limits,
// outputs), in model_section.cpp (model), initial_section.cpp (the initial state and the checks
// at t0) and experiments.cpp (experiments); build.hpp declares what they share.
#include "refdyn/scenario/problem.hpp"

#include "build.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/scenario/schema.hpp"

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

namespace refdyn {

namespace build {

namespace fs = std::filesystem;

std::string substitute(std::string s, const std::string& var, double v) {
  const std::string pat = "{" + var + "}";
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  for (size_t pos; (pos = s.find(pat)) != std::string::npos;) s.replace(pos, pat.size(), b);
  return s;
}

/// Runs an experiment expands into, as a double (a grid's product may exceed every integer).
/// Checks a Monte Carlo experiment's `samples`: a whole number >= 1.
double experiment_runs(const SpecReader& c, const ExperimentSpec& e) {
  if (!e.sweep_parameter.empty()) return static_cast<double>(e.sweep_values.size());
  if (!e.grid.empty()) {
    double n = 1;
    for (const auto& axis : e.grid) n *= static_cast<double>(axis.second.size());
    return n;
  }
  if (e.monte_carlo) {
    const std::string key = e.key + ".monte_carlo.samples";
    const double x = c.number(e.monte_carlo->samples, key);
    if (!(x >= 1 && x <= 9e15 && x == std::floor(x)))
      c.fail(e.monte_carlo->samples, key, "expected a whole number >= 1 of samples, got " + fmt(x));
    return x;
  }
  return 1;
}

/// Reads a force list. Signal columns (a flexible drive's psi_dr, tau_drive) are suffixed
/// "_<name>" for a named element; an unnamed element keeps the bare names unless another
/// element of the list records the same name, then it is suffixed "_<joint>" (two unnamed drives
/// on different joints: psi_dr_j1, psi_dr_j2; a single unnamed drive keeps psi_dr). Names that
/// still coincide are an error.
void read_forces(const SpecReader& c, const std::vector<EntrySpec>& entries, const Model& m, ForceSet& out) {
  std::vector<NewForceElement> built;  // labelled here, then published to `out`
  for (const EntrySpec& e : entries) {
    NewForceElement f =
        build_entry(c, force_kinds(), e, "type", [&](const ForceKind& k) { return k.build(EntryArgs{c, e, m}); });
    f->label = e.name;
    built.push_back(std::move(f));
  }
  std::map<std::string, int> uses;
  for (const auto& f : built)
    for (const auto& s : f->signal_names()) ++uses[s];
  for (size_t i = 0; i < built.size(); ++i) {
    const SpecValue& joint = entries[i].fields["joint"];
    if (!entries[i].name.empty() || !joint.is_scalar() || joint.text.empty()) continue;
    for (const auto& s : built[i]->signal_names())
      if (uses[s] > 1) {
        built[i]->label = joint.text;
        break;
      }
  }
  std::set<std::string> signal_names;
  const size_t states_before = static_cast<size_t>(out.num_states());
  for (size_t i = 0; i < built.size(); ++i) {
    for (const auto& s : built[i]->signal_names())
      if (!signal_names.insert(s).second)
        c.fail(entries[i].fields, entries[i].key,
               "two force elements record '" + s + "' (give each a different 'name:')");
    out.add(built[i]);
  }
  // State columns (LuGre's z_<joint>) are told apart by ForceSet::state_names; names that still
  // coincide (e.g. an element named "2" next to two unnamed ones) are an error.
  std::set<std::string> state_names;
  const auto states = out.state_names();
  for (size_t i = 0, k = states_before; i < built.size(); ++i)
    for (int s = 0; s < built[i]->num_states(); ++s, ++k)
      if (!state_names.insert(states[k]).second)
        c.fail(entries[i].fields, entries[i].key,
               "two force elements have the state '" + states[k] + "' (give each a different 'name:')");
}

/// A count for messages: a whole number when it fits, else in exponent form.
std::string count_text(double x) {
  return x < 9e15 ? std::to_string(static_cast<long long>(x)) : fmt(x);
}

/// Names become CSV headers, JSON strings and (experiments) file names: printable UTF-8.
void check_name(const SpecReader& c, const SpecValue& at, const std::string& key, const std::string& name) {
  if (name.empty()) c.fail(at, key, "expected a name, got an empty one");
  if (name.size() > 200) c.fail(at, key, "a name of " + std::to_string(name.size()) + " bytes; at most 200");
  if (!valid_utf8(name)) c.fail(at, key, "the name is not valid UTF-8 text (hint: save the file as UTF-8)");
  for (unsigned char ch : name)
    if (ch < 0x20 || ch == 0x7f) c.fail(at, key, "the name contains a control character");
}

}  // namespace build

using namespace build;

std::vector<int> Problem::report_point_indices() const {
  std::vector<int> idx;
  for (const auto& p : report_points) idx.push_back(model.point_index(p));
  return idx;
}

std::unique_ptr<ReferenceDynamics> Problem::make_reference_dynamics() const {
  return std::make_unique<ReferenceDynamics>(model, forces, constraints, options);
}

std::unique_ptr<Planner> Problem::make_planner(ReferenceDynamics* rd) const {
  if (is_jerk_problem())
    return std::make_unique<JerkPlanner>(
        std::make_unique<JerkDynamics>(model, constraints, jerk_options(), &forces));
  if (rd) return std::make_unique<ReferencePlanner>(*rd);
  return std::make_unique<ReferencePlanner>(make_reference_dynamics());
}

JerkDynamicsOptions Problem::jerk_options() const {
  JerkDynamicsOptions o;
  o.kappa = kappa;
  o.alpha = options.alpha;
  o.beta = options.beta;
  o.beta_first_order = options.beta_first_order;
  o.consistent_with = qdd_consistent_with;
  return o;
}

Eigen::VectorXd Problem::initial_state(Planner& planner) const {
  return planner.initial_state(integrator.t0, q0, qd0, qdd0.size() ? &qdd0 : nullptr);
}

PlanSettings Problem::plan_settings(const std::function<void(double)>& progress) const {
  PlanSettings s;
  s.integrator = integrator;
  s.residual_from = residual_from;
  s.record.points = report_point_indices();
  s.record.residual_tolerance = residual_tolerance;
  s.progress = progress;
  return s;
}

void check_output_name(const SpecReader& c, const SpecValue& at, const std::string& key, const std::string& name,
                       const std::string& what) {
  check_name(c, at, key, name);
  for (unsigned char ch : name)
    if (!(std::isalnum(ch) || ch == '.' || ch == '_' || ch == '-' || ch == '+' || ch == '='))
      c.fail(at, key,
             "the " + what + " name '" + name + "' is used in a file name and may contain only letters, digits and . _ - + "
             "= (got '" + std::string(1, static_cast<char>(ch)) + "')");
  if (name[0] == '.' || name[0] == '-') c.fail(at, key, "the " + what + " name '" + name + "' may not start with '.' or '-'");
}

std::string substitute_value(std::string name_template, const std::string& parameter, double value) {
  return substitute(std::move(name_template), parameter, value);
}

SpecReader parameter_reader(const ScenarioSpec& spec) {
  SpecReader c(spec.file, {});
  c.params["deg"] = std::numbers::pi / 180.0;
  for (const auto& [name, value] : spec.parameters) {
    if (name == "pi" || name == "e" || name == "deg" || name == "t")
      c.fail(value, "parameters." + name, "'" + name + "' is a reserved name (a constant or the time); choose another name");
    const auto set = spec.parameter_values.find(name);
    if (value.is_list()) {  // a list parameter: each element a number or an expression of the parameters before it
      const std::string key = "parameters." + name;
      if (set != spec.parameter_values.end())
        c.fail(value, key, "'" + name + "' is a list parameter and cannot be set to one number (" + set->second.text + ")");
      if (value.size() == 0)
        c.fail(value, key, "expected a list of numbers [x1, x2, …] (a list parameter), got an empty list");
      if (value.size() > kMaxListParameter)
        c.fail(value, key,
               "a list parameter holds at most " + std::to_string(kMaxListParameter) + " values, got " +
                   std::to_string(value.size()) + " (a time law of that many parts is beyond any plan; use fewer knots)");
      std::vector<Quantity>& out = c.lists[name];
      const auto lv = spec.list_values.find(name);
      if (lv != spec.list_values.end() && lv->second.size() != value.size())
        c.fail(value, key, "set to " + std::to_string(lv->second.size()) + " values where the list has " + std::to_string(value.size()));
      for (size_t i = 0; i < value.size(); ++i) {
        if (lv != spec.list_values.end())
          out.push_back(Quantity{lv->second[i], fmt(lv->second[i]), value[i].where, true});
        else
          out.push_back(c.quantity(value[i], key + "[" + std::to_string(i) + "]"));
      }
      continue;
    }
    c.params[name] = set != spec.parameter_values.end() ? set->second.value : c.number(value, "parameters." + name);
  }
  return c;
}

namespace {

/// time_law: {task_duration, segments: [d1, …, dK]} or {task_duration, knot_speeds: [v1, …, v_{K−1}]}
/// → c.time_law (docs/scenario.md "time_law").
void read_time_law(SpecReader& c, const ScenarioSpec& spec) {
  const SpecValue& tl = spec.time_law;
  if (!tl) return;
  c.keys(tl, "time_law", schema::keys("time_law"));
  const Quantity Tp = c.quantity(c.need(tl, "task_duration", "time_law"), "time_law.task_duration");
  if (!(Tp.value > 0))
    c.fail(tl["task_duration"], "time_law.task_duration", "expected the task's duration > 0 [s], got " + fmt(Tp.value));
  if (tl["segments"] && tl["knot_speeds"])
    c.fail(tl["knot_speeds"], "time_law.knot_speeds",
           "segments and knot_speeds are two forms of the time law and exclude each other; keep one");
  const bool speeds = static_cast<bool>(tl["knot_speeds"]);
  const std::string key = speeds ? "knot_speeds" : "segments";
  const SpecValue& seg = speeds ? tl["knot_speeds"] : c.need(tl, "segments", "time_law");
  std::vector<Number> d;  // the durations or knot speeds, from a list parameter or written in place
  if (seg.is_scalar()) {  // the compact form: the name of a list parameter, `knot_speeds: v`
    const auto it = c.lists.find(seg.text);
    if (it == c.lists.end()) {
      std::vector<std::string> lists;
      for (const auto& l : c.lists) lists.push_back(l.first);
      c.fail(seg, "time_law." + key,
             "expected a list [" + std::string(speeds ? "v1, v2, …" : "d1, d2, …") + "] or the name of a list parameter, and '" +
                 seg.text + "' is " + (c.params.count(seg.text) ? "a parameter with one value" : "no parameter") +
                 " (hint: parameters: {" + seg.text + ": [" + (speeds ? "0.5, 0.5, …" : "0.1, 0.1, …") + "]})" +
                 did_you_mean(seg.text, lists));
    }
    for (size_t i = 0; i < it->second.size(); ++i) {
      const Quantity& q = it->second[i];
      if (!(q.value > 0))
        c.fail(q.where, "parameters." + seg.text + "[" + std::to_string(i) + "]",
               (speeds ? "a knot speed of time_law.knot_speeds must be > 0, got " : "a duration of time_law.segments must be > 0 [s], got ") +
                   fmt(q.value) + (q.literal ? "" : " (" + q.text + ")"));
      d.push_back(q.number());
    }
  } else {
    if (!seg.is_list() || seg.size() == 0)
      c.fail(seg, "time_law." + key,
             (speeds ? std::string("expected a list of K - 1 > 0 task speeds [v1, v2, …] (ṡ at the inner knots i·Tp/K), got ")
                     : std::string("expected a list of K > 0 durations [d1, d2, …] (the real time of each of K equal parts of task time), got ")) +
                 (seg.is_list() ? std::string("an empty list") : seg.describe()));
    for (size_t i = 0; i < seg.size(); ++i) {
      const std::string k = "time_law." + key + "[" + std::to_string(i) + "]";
      const Quantity q = c.quantity(seg[i], k);
      if (!(q.value > 0))
        c.fail(seg[i], k, (speeds ? "expected a task speed > 0, got " : "expected a duration > 0 [s], got ") + fmt(q.value) +
                              (q.literal ? "" : " (" + q.text + ")"));
      d.push_back(q.number());
    }
  }
  try {
    c.time_law = std::make_shared<const TimeLaw>(speeds ? TimeLawForm::knot_speeds : TimeLawForm::segments, Tp.number(),
                                                 std::move(d));
  } catch (const Error& e) {
    c.fail(tl, "time_law", e.what());
  }
}

/// integrator.t1: end — the end of the scenario's time law (docs/scenario.md "time_law").
bool t1_is_end(const SpecValue& t1) { return t1 && t1.is_scalar() && t1.text == "end"; }

/// constraints: (URDF <mimic> couplings first) and forces, each named before it is published.
void build_constraints_and_forces(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  // URDF <mimic> joints: material couplings, before the file's own constraints.
  for (const MimicSpec& mm : spec.model.mimics) {
    try {
      NewConstraint con = joint_coupling(m, mm.joint, mm.leader, mm.multiplier, mm.offset, ConstraintOrigin::Material);
      con->name = "mimic_" + mm.joint;
      s.constraints.add(con);
    } catch (const Error& e) {
      c.fail(spec.model.value["urdf"], "model.urdf", e.what());
    }
  }
  for (const EntrySpec& e : spec.constraints) {
    const ConstraintKind* kind = constraint_kinds().find(e.kind);
    ConstraintOrigin origin = kind ? kind->default_origin : ConstraintOrigin::Programmed;
    if (e.fields["origin"])
      origin = c.choice(e.fields["origin"], e.key + ".origin", {"material", "programmed"}) == "material"
                   ? ConstraintOrigin::Material : ConstraintOrigin::Programmed;
    NewConstraint con = build_entry(c, constraint_kinds(), e, "kind",
                                    [&](const ConstraintKind& k) { return k.build(EntryArgs{c, e, m}, origin); });
    check_name(c, e.fields["name"], e.key + ".name", e.name);
    con->name = e.name;
    if (e.fields["record"]) {
      con->record_as = c.string(e.fields["record"], e.key + ".record");
      if (!con->target()) c.fail(e.fields["record"], e.key + ".record", "this constraint prescribes no function of time to record");
    }
    try {
      s.constraints.add(con);
    } catch (const Error& err) {
      c.fail(e.fields, e.key, err.what());
    }
  }
  read_forces(c, spec.forces, m, s.forces);
}

/// Jerk-level problems (a row of order 3): rows of every order ≤ 3 beside the jerk rows,
/// experiments; docs/higher_order.md. (Force elements with a rate: check_capabilities.)
void check_jerk_scope(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  for (int k = 0; k < s.constraints.size(); ++k)
    if (JerkConstraintPtr j = jerk_constraint_of(*s.constraints.constraints()[k])) s.jerk_constraints.push_back(j);
  if (!s.is_jerk_problem()) return;
  // A plan of jerk rows alone reports the dynamics residual and is not cut at a tolerance; rows
  // of order ≤ 2 beside them are (plan_jerk_motion).
  if (static_cast<int>(s.jerk_constraints.size()) == s.constraints.size())
    s.residual_tolerance = std::numeric_limits<double>::infinity();
}

/// baumgarte, solver and partition: the reference-dynamics options.
void build_reference_options(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  {
    const BaumgarteSpec& b = spec.baumgarte;
    if (b.alpha) s.options.alpha = c.number(b.alpha, "baumgarte.alpha");
    if (b.beta) s.options.beta = c.number(b.beta, "baumgarte.beta");
    if (b.beta_first_order) s.options.beta_first_order = c.number(b.beta_first_order, "baumgarte.beta_first_order");
    try {
      s.options.validate();
    } catch (const Error& e) {
      c.fail(b.value, "baumgarte", e.what());
    }
  }
  s.options.solver = spec.solver == "lagrange" ? ReferenceSolver::Lagrange
                      : spec.solver == "auto"   ? automatic_reference_solver(m.nq, s.constraints.rows())
                                                : ReferenceSolver::Projection;
  s.options.paper_literal_forces = spec.paper_literal_forces;
  if (const StabilizationSpec& st = spec.stabilization; st.value) {
    const SpecValue& at = st.value;
    s.options.stabilization = st.method == "projection" ? Stabilization::Projection
                              : st.method == "both"     ? Stabilization::Both
                                                        : Stabilization::Baumgarte;
    if (s.options.stabilization != Stabilization::Baumgarte) {
      if (s.is_jerk_problem())
        c.fail(at, "stabilization", "projection is not available for problems with jerk constraints (order: jerk) "
                                    "(hint: remove stabilization)");
      bool state_rows = false;
      for (int r = 0; r < s.constraints.rows(); ++r) state_rows = state_rows || s.constraints.row_order(r) <= 1;
      if (!state_rows)
        c.fail(at, "stabilization", "projection needs position or velocity constraints to project onto, and this "
                                    "problem has none (hint: stabilization: baumgarte, or remove the key)");
      if (s.options.stabilization == Stabilization::Projection && spec.baumgarte.value)
        c.fail(spec.baumgarte.value, "baumgarte",
               "stabilization: projection uses no Baumgarte gains (the rows are imposed as Phi'' = 0, c' = 0); "
               "remove baumgarte: or write stabilization: both");
    }
    if (st.tolerance) s.options.projection_tolerance = c.number(st.tolerance, "stabilization.tolerance");
    if (st.max_iterations) {
      const double k = c.number(st.max_iterations, "stabilization.max_iterations");
      if (!(k >= 1 && k <= 1000 && k == std::floor(k)))
        c.fail(st.max_iterations, "stabilization.max_iterations", "expected a whole number from 1 to 1000, got " + fmt(k));
      s.options.projection_max_iterations = static_cast<int>(k);
    }
    try {
      s.options.validate();
    } catch (const Error& e) {
      c.fail(at, "stabilization", e.what());
    }
  }

  const int nrows = s.constraints.rows();
  if (nrows > m.nq)
    c.fail(spec.constraints_value, "constraints",
           "expected at most " + std::to_string(m.nq) + " constraint rows (one per coordinate), got " + std::to_string(nrows));
  const PartitionSpec& part = spec.partition;
  s.automatic_independent = part.automatic;
  if (!part.automatic) {
    const SpecValue& ind = part.independent_value;
    if (static_cast<int>(part.independent.size()) != m.nq - nrows)
      c.fail(ind, "partition.independent",
             "expected " + std::to_string(m.nq - nrows) + " independent coordinates (" + std::to_string(m.nq) +
                 " coordinates minus " + std::to_string(nrows) + " constraint rows), got " +
                 std::to_string(part.independent.size()) + " (joints: " + SpecReader::joint_list(m) + ")");
    for (size_t i = 0; i < part.independent.size(); ++i) {
      const std::string& j = part.independent[i];
      c.joint(ind[i], "partition.independent", m);
      if (std::find(s.options.independent.begin(), s.options.independent.end(), j) != s.options.independent.end())
        c.fail(ind[i], "partition.independent", "joint '" + j + "' is listed twice");
      s.options.independent.push_back(j);
    }
  }
  if (part.automatic_switch) s.options.automatic_partition = c.boolean(part.automatic_switch, "partition.automatic_switch");
  if (part.max_condition) {
    s.options.max_condition = c.number(part.max_condition, "partition.max_condition");
    if (!(s.options.max_condition > 1)) c.fail(part.max_condition, "partition.max_condition", "expected a value > 1");
  }
}

/// integrator: method, span, step, tolerances, the residual window.
void build_integrator(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  {
    const IntegratorSpec& in = spec.integrator;
    IntegratorOptions& o = s.integrator;
    from_string(in.method, o.method);  // the reader accepted only the methods' names
    if (o.method == IntegratorMethod::BDF && s.is_jerk_problem())
      c.fail(spec.integrator.value["method"], "integrator.method",
             "method: bdf is not available for problems with jerk constraints (order: jerk) yet: their reference "
             "dynamics has no exact Jacobian (hint: method: rk4 or dopri5)");
    if (in.max_order) {
      const double k = c.number(in.max_order, "integrator.max_order");
      if (o.method != IntegratorMethod::BDF)
        c.fail(in.max_order, "integrator.max_order", "is an option of method: bdf only (this integrator is " +
                                                         std::string(to_string(o.method)) + "); remove it or set method: bdf");
      if (!(k >= 1 && k <= 5 && k == std::floor(k)))
        c.fail(in.max_order, "integrator.max_order", "expected a whole number from 1 to 5 (the BDF order), got " + fmt(k));
      o.max_order = static_cast<int>(k);
    }
    if (in.step) o.step = c.number(in.step, "integrator.step");
    if (in.t0) o.t0 = c.number(in.t0, "integrator.t0");
    if (t1_is_end(in.t1)) {
      if (!c.time_law)
        c.fail(in.t1, "integrator.t1", "'end' is the end of the scenario's time_law, and this scenario has none (hint: write t1 as a time [s])");
      o.t1 = c.time_law->end_time();
    } else if (in.t1) {
      o.t1 = c.number(in.t1, "integrator.t1");
    }
    if (in.rtol) o.rtol = c.number(in.rtol, "integrator.rtol");
    if (in.atol) o.atol = c.number(in.atol, "integrator.atol");
    if (in.output_interval) o.output_interval = c.number(in.output_interval, "integrator.output_interval");
    if (c.time_law)  // s̈ jumps at the knots: the integrators step onto them (IntegratorOptions::breakpoints)
      for (double tk : c.time_law->knots())
        if (tk > o.t0 && tk < o.t1 && (o.breakpoints.empty() || tk > o.breakpoints.back())) o.breakpoints.push_back(tk);
    o.min_step = in.min_step ? c.number(in.min_step, "integrator.min_step") : std::min(o.min_step, 0.5 * o.step);
    if (in.residual_from) s.residual_from = c.number(in.residual_from, "integrator.residual_from");
    if (in.residual_tolerance) {
      const SpecValue& rt = in.residual_tolerance;
      if (s.is_jerk_problem() && static_cast<int>(s.jerk_constraints.size()) == s.constraints.size())
        c.fail(rt, "integrator.residual_tolerance",
               "not for problems with only jerk constraints (order: jerk): their plan's residual is that of the "
               "dynamics and is not checked against a tolerance (docs/higher_order.md; the tolerance applies to "
               "rows of order position, velocity or acceleration beside them); remove it");
      if (rt.is_scalar() && (rt.text == "none" || rt.text == "off")) {
        s.residual_tolerance = std::numeric_limits<double>::infinity();
      } else {
        s.residual_tolerance = c.number(rt, "integrator.residual_tolerance");
        if (!(s.residual_tolerance > 0))
          c.fail(rt, "integrator.residual_tolerance",
                 "expected a tolerance > 0 (or 'none' for no check), got " + fmt(s.residual_tolerance));
      }
    }
    try {
      o.validate();
    } catch (const Error& e) {
      c.fail(in.value, "integrator", e.what());
    }
    // One step over the whole span (or more) is no plan: RK4 would take a single step and report
    // its end, whatever the motion did in between.
    if (o.step > o.t1 - o.t0)
      c.fail(in.step ? in.step : in.value, "integrator.step",
             "the step " + fmt(o.step) + " s is longer than the time span t1 - t0 = " + fmt(o.t1 - o.t0) +
                 " s (hint: a step of a few milliseconds; the default is 1e-3)");
  }
}

/// limits: steps and samples of a run, number of runs, checked before any work.
void build_limits(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  // Limits, before any work: steps and samples of a run, number of runs.
  {
    Limits& lim = s.limits;
    auto count = [&](const char* k, long& v) {
      if (const SpecValue& n = spec.limits[k]) {
        const double x = c.number(n, std::string("limits.") + k);
        if (!(x >= 1 && x <= 9e15 && x == std::floor(x))) c.fail(n, std::string("limits.") + k, "expected a whole number >= 1, got " + fmt(x));
        v = static_cast<long>(x);
      }
    };
    count("max_steps", lim.max_steps);
    count("max_samples", lim.max_samples);
    count("max_runs", lim.max_runs);
    // Every run is built here (its values drawn, its controller and forces made): a ceiling that
    // keeps the build of a scenario within seconds and a few hundred MB whatever the file says.
    if (lim.max_runs > kMaxRunsCeiling)
      c.fail(spec.limits["max_runs"], "limits.max_runs",
             "at most " + std::to_string(kMaxRunsCeiling) + " runs per scenario, got " + std::to_string(lim.max_runs) +
                 " (hint: split the study into several scenarios, e.g. Monte Carlo with other seeds)");
    IntegratorOptions& o = s.integrator;
    const double span = o.t1 - o.t0;
    const SpecValue& at = spec.integrator.value ? spec.integrator.value : spec.root;
    double samples;
    if (o.method == IntegratorMethod::RK4) {
      // with breakpoints (a time law's knots) each part has its own ⌈part/step⌉ steps: at most one more per part
      const double steps = std::ceil(span / o.step - 1e-9) + static_cast<double>(o.breakpoints.size());
      if (steps > static_cast<double>(lim.max_steps))
        c.fail(at, "integrator",
               "(t1 - t0)/step = " + count_text(steps) + " steps, more than limits.max_steps = " + std::to_string(lim.max_steps) +
                   " (hint: a larger step or a shorter span; or raise limits.max_steps)");
      const double every = o.output_interval > 0 ? std::max(1.0, std::round(o.output_interval / (span / steps))) : 1.0;
      samples = std::floor(steps / every) + 2;
    } else {
      samples = std::floor(span / (o.output_interval > 0 ? o.output_interval : o.step)) + 2;
    }
    o.max_steps = lim.max_steps;
    if (samples > static_cast<double>(lim.max_samples))
      c.fail(at, "integrator",
             count_text(samples) + " output samples, more than limits.max_samples = " + std::to_string(lim.max_samples) +
                 " (hint: set integrator.output_interval, shorten the span, or raise limits.max_samples)");
    // Counted (in double: no overflow) before anything is expanded or drawn.
    double runs = 0, largest = 0;
    const ExperimentSpec* biggest = nullptr;
    for (const ExperimentSpec& e : spec.experiments) {
      const double n = experiment_runs(c, e);
      runs += n;
      if (n > largest) {
        largest = n;
        biggest = &e;
      }
    }
    if (runs > static_cast<double>(lim.max_runs))
      c.fail(spec.experiments_value, "experiments",
             count_text(runs) + " runs after expanding the sweeps, grids and Monte Carlo samples" +
                 (biggest && largest < runs ? " (" + biggest->key + " gives " + count_text(largest) + ")" : "") +
                 ", more than limits.max_runs = " + std::to_string(lim.max_runs) +
                 " (hint: fewer sweep or grid values or samples, or raise limits.max_runs)");
  }
}

/// outputs: the points recorded in trajectories.
void build_outputs(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  if (spec.output_points) {
    for (const SpecValue& p : *spec.output_points) s.report_points.push_back(c.point(p, "outputs.points", m));
  } else {
    s.report_points = m.point_name;
  }
}

}  // namespace

std::unique_ptr<Problem> build_problem(const ScenarioSpec& spec) {
  SpecReader c = parameter_reader(spec);
  read_time_law(c, spec);
  std::unique_ptr<Problem> s = build_model_section(c, spec);
  for (const auto& [name, value] : spec.parameters) {
    if (value.is_list()) continue;  // a list parameter's elements are numbers to the symbolic layer
    const auto set = spec.parameter_values.find(name);
    s->texts.parameters.emplace_back(name, set != spec.parameter_values.end() ? symbolic_number(set->second.value) : value.text);
  }
  s->texts.t0 = spec.integrator.t0.text;
  s->t1_is_law_end = t1_is_end(spec.integrator.t1) && c.time_law;
  s->texts.t1 = s->t1_is_law_end ? std::string() : spec.integrator.t1.text;  // the law's end: its own derivative
  if (c.time_law) {
    s->time_law_knots = c.time_law->knots();
    s->time_law = c.time_law;
  }
  build_constraints_and_forces(c, spec, *s);
  if (c.time_law && c.retimed == 0)
    c.fail(spec.time_law, "time_law",
           "a time law retimes the functions of time of programmed constraints and force profiles, and this scenario "
           "has none: it has nothing to retime (hint: write the task's motion with a `function:` key in t, or remove "
           "time_law)");
  check_jerk_scope(c, spec, *s);
  build_reference_options(c, spec, *s);
  build_initial(c, spec, *s);
  build_integrator(c, spec, *s);
  check_capabilities(c, spec, *s);
  build_limits(c, spec, *s);
  check_initial_state(c, spec, *s);
  build_experiments(c, spec, *s);
  build_outputs(c, spec, *s);
  return s;
}

Plan plan_problem(const Problem& p, Planner& planner, const std::function<void(double)>& progress) {
  return planner.plan(p.initial_state(planner), p.plan_settings(progress));
}

Plan plan_problem(const Problem& p, ReferenceDynamics& rd, const std::function<void(double)>& progress) {
  return plan_problem(p, *p.make_planner(&rd), progress);
}

ClosedLoopResult track_experiment(const Problem& p, const Experiment& ex, const Plan& plan, ReferenceDynamics& rd,
                                  const std::function<void(double)>& progress) {
  return track_experiment(p, ex, plan, *p.make_planner(&rd), progress);
}

ClosedLoopResult track_experiment(const Problem& p, const Experiment& ex, const Plan& plan, Planner& planner,
                                  const std::function<void(double)>& progress) {
  const Model& m = p.model;
  const int n = m.nv;
  std::unique_ptr<Controller> ctrl = ex.make_controller(m);
  ClosedLoopOptions o;
  o.integrator = p.integrator;
  o.integrator.t1 = std::min(p.integrator.t1, plan.summary.t_end);
  o.effort_limit = p.effort_limit;
  o.progress = progress;
  o.points = p.report_point_indices();
  o.material = p.material.get();
  o.plant = p.options;
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(2 * n + ex.plant_forces.num_states());
  x0.head(n) = ex.q0;
  x0.segment(n, n) = ex.qd0;
  double dq = 0, dqd = 0;
  if (p.material) {  // a start the machine can have: dependent coordinates and velocities solved
    ReferenceDynamicsOptions po = p.options;
    po.independent.clear();
    for (int j : ctrl->actuation().independent) po.independent.push_back(m.joint_name[j]);
    po.automatic_partition = false;
    const ForceSet none;
    ReferenceDynamics plant(m, none, *p.material, po);
    const ReferenceDynamics::Consistency c = plant.make_consistent(o.integrator.t0, ex.q0, ex.qd0);
    if (!c.converged || !(c.residual_after <= p.initial_tolerance)) {
      ClosedLoopResult r;
      r.joints = m.joint_name;
      r.summary.status = IntegrationStatus::NumericalFailure;
      r.summary.t_end = o.integrator.t0;
      r.summary.message = "the start cannot satisfy the material constraints: with the independent coordinates " +
                          Actuation::names(m, ctrl->actuation().independent) + " as given, the Newton solve for " +
                          Actuation::names(m, ctrl->actuation().dependent) + " left a residual of " +
                          fmt(c.residual_after) + " (was " + fmt(c.residual_before) +
                          "): the initial error is too large for the mechanism to assemble";
      return r;
    }
    x0.head(n) = c.q;
    x0.segment(n, n) = c.qd;
    dq = c.dq.size() ? c.dq.cwiseAbs().maxCoeff() : 0.0;
    dqd = c.dqd.size() ? c.dqd.cwiseAbs().maxCoeff() : 0.0;
  }
  ClosedLoopResult r = simulate_closed_loop(m, ex.plant_forces, *ctrl, plan, &planner, x0, o);
  r.initial_correction_q = dq;
  r.initial_correction_qd = dqd;
  r.summary.max_constraint_residual = r.max_material_residual;
  // A run that tracked a plan to its end is a success only when the plan was: else it tracked
  // the valid part of a reference that stopped early, and says so.
  if (r.summary.ok() && !plan.summary.ok()) {
    r.summary.status = IntegrationStatus::ReferenceStopped;
    r.summary.message = "tracked the reference up to t = " + fmt(r.summary.t_end) + " s, where the plan stopped (" +
                        to_string(plan.summary.status) + "; the plan's reason: summary.json plan.message)";
  }
  return r;
}

}  // namespace refdyn
