// build_problem: a ScenarioSpec (as written) becomes a checked Problem. The section builders
// are here (constraints and forces, jerk scope, reference options, initial state, integrator,
// limits, t0 checks, outputs), in model_section.cpp (model) and experiments.cpp (experiments);
// build.hpp declares what they share.
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

/// Everything a run evaluates at t0 is finite and the constraint rows are independent; else an
/// error naming the constraint (or section) responsible.
void check_at_t0(const SpecReader& c, const ScenarioSpec& spec, const Problem& p) {
  const Model& m = p.model;
  const ConstraintSet& cs = p.constraints;
  const double t0 = p.integrator.t0;
  const int nmimic = cs.size() - static_cast<int>(spec.constraints.size());
  auto entry_of = [&](int row) -> std::pair<const SpecValue*, std::string> {
    const int k = cs.row_owner(row);
    if (k < nmimic) return {&spec.model.value, "model.urdf"};
    const EntrySpec& e = spec.constraints[k - nmimic];
    return {&e.fields, e.key};
  };
  Data data(m);
  ConstraintEval ev(m, cs);
  try {
    evaluate_constraints(m, data, cs, ev, t0, p.q0, p.qd0);
  } catch (const Error& e) {
    c.fail(spec.constraints_value, "constraints", std::string("at t0 = ") + fmt(t0) + " s: " + e.what());
  }
  for (int row = 0; row < cs.rows(); ++row)
    if (!std::isfinite(ev.phi[row]) || !std::isfinite(ev.phid[row]) || !std::isfinite(ev.gamma[row]) ||
        !ev.A.row(row).allFinite()) {
      const auto [at, key] = entry_of(row);
      c.fail(*at, key,
             "constraint row '" + cs.row_name(row) + "' is not finite at t0 = " + fmt(t0) + " s (Phi = " +
                 fmt(ev.phi[row]) + ", gamma = " + fmt(ev.gamma[row]) +
                 "): check its domain at the initial state (a square root or logarithm of a negative number, a "
                 "division by zero)");
    }
  // Independent rows: add them one by one; a row that does not raise the rank is redundant.
  if (cs.rows() > 0) {
    Eigen::MatrixXd A = ev.A;  // rows normalised: the test is on directions, not on units
    for (int row = 0; row < cs.rows(); ++row)
      if (A.row(row).norm() > 0) A.row(row).normalize();
    for (int row = 0; row < cs.rows(); ++row) {
      Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(row + 1, m.nv);
      qr.setThreshold(1e-9);
      qr.compute(A.topRows(row + 1));
      if (A.row(row).norm() == 0 && cs.row_order(row) == 2) {
        const auto [at, key] = entry_of(row);
        c.fail(*at, key,
               "acceleration constraint row '" + cs.row_name(row) + "' does not act on the accelerations at t0 = " +
                   fmt(t0) + " s (B = d/dqdd of the expression is zero there): it cannot be imposed; start where "
                   "it involves qdd, or write it differently");
      }
      if (A.row(row).norm() == 0 || qr.rank() < row + 1) {
        const auto [at, key] = entry_of(row);
        c.fail(*at, key,
               "constraint row '" + cs.row_name(row) + "' depends linearly on the rows before it at t0 = " + fmt(t0) +
                   " s (the constraint Jacobian has rank " + std::to_string(A.row(row).norm() == 0 ? row : qr.rank()) +
                   " < " + std::to_string(row + 1) + "): the constraints are redundant or singular there; remove one "
                   "or start elsewhere");
      }
    }
  }
  {  // A joint that moves no mass makes M singular: name it.
    const Eigen::MatrixXd M = mass_matrix(m, data, p.q0);
    const Eigen::LLT<Eigen::MatrixXd> llt(M);
    const double tiny = 1e-12 * std::max(1.0, M.diagonal().cwiseAbs().maxCoeff());
    if (!M.allFinite()) {
      int j = 0;
      for (int i = 0; i < m.nv; ++i)
        if (!M.row(i).allFinite()) {
          j = i;
          break;
        }
      c.fail(spec.model.value, "model",
             "the mass matrix is not a finite number at the initial state (row of joint '" + m.joint_name[j] +
                 "': an overflow; masses, lengths or inertias too large, e.g. a wrong unit)");
    }
    if (llt.info() != Eigen::Success || (M.diagonal().array() <= tiny).any()) {
      int j = 0;
      for (int i = 0; i < m.nv; ++i)
        if (!(M(i, i) > tiny)) {
          j = i;
          break;
        }
      c.fail(spec.model.value, "model",
             "the mass matrix is singular at the initial state: joint '" + m.joint_name[j] +
                 "' moves no mass or inertia (hint: give the links it carries a mass and an inertia)");
    }
  }
  Eigen::VectorXd Q(m.nv), zdot(std::max(1, p.forces.num_states()));
  const Eigen::VectorXd z = Eigen::VectorXd::Zero(std::max(1, p.forces.num_states()));
  p.forces.evaluate(t0, p.q0, p.qd0, z.data(), Q, zdot.data());
  for (size_t k = 0; k < p.forces.elements().size(); ++k) {
    const Eigen::VectorXd f = p.forces.element_force(static_cast<int>(k), t0, p.q0, p.qd0, z.data());
    if (!f.allFinite() && k < spec.forces.size())
      c.fail(spec.forces[k].fields, spec.forces[k].key,
             "the force of '" + p.forces.elements()[k]->name() + "' is not finite at t0 = " + fmt(t0) + " s");
  }
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
  c.keys(tl, "time_law", {"task_duration", "segments", "knot_speeds"});
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

/// The texts of a joint vector as written (a list, or a mapping joint: value), "" where absent.
std::vector<std::string> joint_texts(const SpecValue& v, const Model& m) {
  std::vector<std::string> out(static_cast<size_t>(m.nq));
  if (v.is_list()) {
    for (int i = 0; i < m.nq && i < static_cast<int>(v.size()); ++i) out[static_cast<size_t>(i)] = v[static_cast<size_t>(i)].text;
  } else if (v.is_map()) {
    for (const auto& e : v.entries) {
      const auto it = std::find(m.joint_name.begin(), m.joint_name.end(), e.key);
      if (it != m.joint_name.end()) out[static_cast<size_t>(it - m.joint_name.begin())] = e.value.text;
    }
  }
  return out;
}

/// initial: q0, q̇0 (and q̈0, κ for jerk problems).
void build_initial(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  const InitialSpec& ini = spec.initial;
  s.q0 = c.joint_vector(c.need(ini.value, "q", "initial"), "initial.q", m, true, 0.0);
  s.qd0 = ini.qd ? c.joint_vector(ini.qd, "initial.qd", m, false, 0.0) : Eigen::VectorXd::Zero(m.nq);
  s.project_initial = ini.project;
  s.texts.q0 = joint_texts(ini.value["q"], m);
  s.texts.qd0 = joint_texts(ini.qd, m);
  if (ini.tolerance) {
    s.initial_tolerance = c.number(ini.tolerance, "initial.tolerance");
    if (!(s.initial_tolerance > 0)) c.fail(ini.tolerance, "initial.tolerance", "expected a value > 0");
  }
  if (ini.qdd) {
    if (!s.is_jerk_problem())
      c.fail(ini.qdd, "initial.qdd",
             "an initial acceleration is part of the state only in problems with jerk constraints (order: jerk); "
             "elsewhere q̈0 follows from the dynamics (remove it)");
    if (const SpecValue& cw = ini.qdd["consistent_with"]) {
      // initial.qdd: {consistent_with: ROW or [ROWS]}: jerk rows made with differentiate: true.
      if (ini.qdd.size() != 1)
        c.fail(ini.qdd, "initial.qdd",
               "write either the accelerations per joint or {consistent_with: [rows]}, not both");
      const std::vector<SpecValue> rows = cw.is_list() ? cw.items : std::vector<SpecValue>{cw};
      for (const SpecValue& r : rows) {
        if (!r.is_scalar()) c.fail(r, "initial.qdd.consistent_with", "expected a constraint name, got " + r.describe());
        const auto it = std::find_if(s.jerk_constraints.begin(), s.jerk_constraints.end(),
                                     [&](const JerkConstraintPtr& j) { return j->name() == r.text; });
        if (it == s.jerk_constraints.end()) {
          std::vector<std::string> names;
          for (const auto& j : s.jerk_constraints) names.push_back(j->name());
          c.fail(r, "initial.qdd.consistent_with",
                 "'" + r.text + "' is not a jerk constraint (order: jerk) of this scenario" + did_you_mean(r.text, names));
        }
        if ((*it)->source_text().empty())
          c.fail(r, "initial.qdd.consistent_with",
                 "jerk row '" + r.text + "' was written at the jerk level, so there is no acceleration row to be "
                 "consistent with (hint: write it at the acceleration level with differentiate: true, or give "
                 "initial.qdd per joint)");
        s.qdd_consistent_with.push_back(r.text);
      }
    } else {
      s.qdd0 = c.joint_vector(ini.qdd, "initial.qdd", m, true, 0.0);
    }
  }
  if (const SpecValue& k = spec.baumgarte.kappa) {
    if (!s.is_jerk_problem())
      c.fail(k, "baumgarte.kappa", "kappa is the gain of problems with jerk constraints (order: jerk); remove it");
    s.kappa = c.number(k, "baumgarte.kappa");
    if (!(std::isfinite(s.kappa) && s.kappa >= 0))
      c.fail(k, "baumgarte.kappa", "expected a finite value >= 0 [1/s], got " + fmt(s.kappa));
  }
  if (s.is_jerk_problem()) {  // no partition: JerkDynamics solves a KKT system
    s.options.independent.clear();
    s.automatic_independent = false;
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

/// initial.consistency: project — q0, q̇0 moved onto the rows of `rd` (Newton), the moves kept
/// for `refdyn check`.
void project_initial_state(const SpecReader& c, const InitialSpec& ini, ReferenceDynamics& rd, double t0, Problem& s) {
  const auto cons = rd.make_consistent(t0, s.q0, s.qd0, 1e-12);
  if (!cons.converged)
    c.fail(ini.value, "initial", "the Newton projection onto the constraints did not converge (residual " +
                                     fmt(cons.residual_after) + "); start closer to a consistent configuration");
  s.q0 = cons.q;
  s.qd0 = cons.qd;
  s.initial_dq = cons.dq;
  s.initial_dqd = cons.dqd;
}

/// Every row of `set` within the tolerance at the initial state (|Φ| and |Φ̇| from `ev`).
void check_initial_residuals(const SpecReader& c, const InitialSpec& ini, const ConstraintSet& set,
                             const ConstraintEval& ev, double tolerance) {
  for (int row = 0; row < set.rows(); ++row) {
    const double v = std::max(std::abs(ev.phi[row]), std::abs(ev.phid[row]));
    if (!(v <= tolerance))
      c.fail(ini.value, "initial",
             "the initial state violates constraint '" + set.row_name(row) + "' by " + fmt(v) +
                 " (|Phi| or |dPhi/dt|) > tolerance " + fmt(tolerance) +
                 " (hint: set initial.consistency: project, or correct q/qd)");
  }
}

/// The initial state at t0: consistent with the constraints (projected when asked), the
/// partition chosen, every row finite and independent.
void check_initial_state(const SpecReader& c, const ScenarioSpec& spec, Problem& s) {
  const Model& m = s.model;
  const int nrows = s.constraints.rows();
  const PartitionSpec& part = spec.partition;
  const InitialSpec& ini = spec.initial;
  // Initial consistency and partition at t0.
  s.initial_dq = Eigen::VectorXd::Zero(m.nq);
  s.initial_dqd = Eigen::VectorXd::Zero(m.nq);
  if (s.is_jerk_problem()) {
    // Jerk rows restrict neither q0 nor q̇0; the rows of order ≤ 1 do (checked, or projected, as
    // in any problem); q̈0 is made consistent with the dynamics and every row of order ≤ 2.
    // Then the jerk-level system is evaluated once at t0: every row regular and finite.
    const double t0 = s.integrator.t0;
    const int nmimic = s.constraints.size() - static_cast<int>(spec.constraints.size());
    auto entry_of = [&](int row) -> std::pair<const SpecValue*, std::string> {
      const int k = s.constraints.row_owner(row);
      if (k < nmimic) return {&spec.model.value, "model.urdf"};
      const EntrySpec& e = spec.constraints[k - nmimic];
      return {&e.fields, e.key};
    };
    ConstraintSet lower;
    for (int k = 0; k < s.constraints.size(); ++k) {
      const ConstraintPtr& con = s.constraints.constraints()[k];
      if (con->order() == 3) continue;
      lower.add(con);
    }
    if (lower.rows() > 0) {
      ReferenceDynamicsOptions lo = s.options;
      lo.independent.clear();
      ReferenceDynamics rd(m, s.forces, lower, lo);
      if (s.project_initial) project_initial_state(c, ini, rd, t0, s);
      Data data(m);
      ConstraintEval ev(m, lower);
      try {
        evaluate_constraints(m, data, lower, ev, t0, s.q0, s.qd0);
      } catch (const Error& e) {
        c.fail(spec.constraints_value, "constraints", std::string("at t0 = ") + fmt(t0) + " s: " + e.what());
      }
      check_initial_residuals(c, ini, lower, ev, s.initial_tolerance);  // acceleration rows: Φ = Φ̇ = 0
    }
    try {
      JerkDynamics jd(m, s.constraints, s.jerk_options(), &s.forces);
      const Eigen::VectorXd x0 = jd.initial_state(t0, s.q0, s.qd0, s.qdd0.size() ? &s.qdd0 : nullptr);
      Eigen::VectorXd dx(x0.size());
      jd.derivative(t0, x0, dx);
      if (!dx.allFinite()) throw NumericalFailure(t0, "the jerk-level equations are not finite at t0 = " + fmt(t0) + " s");
      for (int r = 0; r < nrows; ++r)
        if (jd.B().row(r).norm() == 0) {
          const auto [at, key] = entry_of(r);
          c.fail(*at, key,
                 "constraint row '" + s.constraints.row_name(r) + "' does not act on its highest derivative at t0 = " +
                     fmt(t0) + " s (" + (s.constraints.row_order(r) == 3 ? "B = d/dqddd" : "its Jacobian") +
                     " is zero there)");
        }
    } catch (const NumericalFailure& e) {
      c.fail(spec.constraints_value, "constraints", e.what());
    } catch (const Error& e) {
      const std::string w = e.what();
      if (w.rfind(c.file(), 0) == 0) throw;
      c.fail(spec.constraints_value, "constraints", std::string("at t0: ") + w);
    }
  } else {
    ReferenceDynamics rd(m, s.forces, s.constraints, s.options);
    const double t0 = s.integrator.t0;
    const SpecValue& where_part = part.value ? part.value : spec.root;
    check_at_t0(c, spec, s);
    try {
      if (s.automatic_independent) {
        rd.choose_partition(t0, s.q0, s.qd0);
        s.options.independent.clear();
        for (int i : rd.independent()) s.options.independent.push_back(m.joint_name[i]);
      }
    } catch (const NumericalFailure& e) {
      c.fail(where_part, "partition", e.what());
    }
    if (s.project_initial) project_initial_state(c, ini, rd, t0, s);
    Eigen::VectorXd x = rd.make_state(s.q0, s.qd0), dx(x.size());
    try {
      rd.residual(t0, x);  // with acceleration rows this solves the dynamics once
    } catch (const NumericalFailure& e) {
      c.fail(where_part, "partition", e.what());
    }
    check_initial_residuals(c, ini, s.constraints, rd.constraints(), s.initial_tolerance);
    if (s.options.solver == ReferenceSolver::Projection && nrows > 0) {
      try {
        rd.derivative(t0, x, dx);
      } catch (const NumericalFailure& e) {
        c.fail(where_part, "partition", e.what());
      }
    }
  }
}

/// Tracking: controller, effort limit and the experiments, expanded into runs.
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
