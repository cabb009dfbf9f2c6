// refdyn check as a library function: the report (check_scenario) and its text (check_text).
#include "refdyn/io/check.hpp"

#include "refdyn/common/text.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/variants.hpp"
#include "refdyn/scenario/problem.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <sstream>

namespace refdyn::io {

namespace {

std::string kind_of(const Constraint& c) {
  return c.order() == 3 ? "jerk-level" : c.order() == 2 ? "acceleration-level" : c.first_order() ? "first-order" : "holonomic";
}

/// printf into a string.
std::string format(const char* f, ...) {
  va_list a, b;
  va_start(a, f);
  va_copy(b, a);
  const int n = std::vsnprintf(nullptr, 0, f, a);
  va_end(a);
  std::string s(static_cast<size_t>(n > 0 ? n : 0) + 1, '\0');
  std::vsnprintf(s.data(), s.size(), f, b);
  va_end(b);
  s.resize(s.size() - 1);
  return s;
}

}  // namespace

CheckReport check_scenario(const ScenarioSpec& spec, const std::string& file) {
  const auto sp = build_problem(spec);
  const std::vector<Variant> variants = expand_variants(spec);  // checked before "valid"
  const Problem& s = *sp;
  const Model& m = s.model;
  // Everything is evaluated before the report is returned: "valid" is never followed by an error.
  const double t0 = s.integrator.t0;
  const auto planner = s.make_planner();
  const Eigen::VectorXd x = s.initial_state(*planner);
  Eigen::VectorXd dx(x.size());
  planner->derivative(t0, x, dx);

  CheckReport r;
  r.name = s.name;
  r.file = file;
  r.model_summary = m.summary();
  r.model_notes = s.model_notes;
  r.joints = m.joint_name;
  r.rows.total = s.constraints.rows();
  for (const auto& c : s.constraints.constraints()) {
    CheckReport::Constraint e;
    e.name = c->name;
    e.origin = to_string(c->origin);
    e.kind = kind_of(*c);
    e.order = c->order();
    e.rheonomic = c->rheonomic();
    e.rows = c->rows();
    e.description = c->describe();
    r.constraints.push_back(e);
    (c->origin == ConstraintOrigin::Material ? r.rows.material : r.rows.programmed) += c->rows();
    (c->order() == 3 ? r.rows.jerk : c->order() == 2 ? r.rows.acceleration : c->first_order() ? r.rows.first_order
                                                                                               : r.rows.holonomic) +=
        c->rows();
  }
  for (const auto& e : s.forces.elements()) r.force_elements.push_back(e->name());
  r.planner_description = planner->description();
  r.t0 = t0;
  if (planner->state_has_acceleration()) {
    CheckInitialAcceleration& a = r.initial_acceleration.emplace();
    a.source = s.qdd0.size() ? "initial.qdd" : s.qdd_consistent_with.empty() ? "free" : "consistent_with";
    a.consistent_with = s.qdd_consistent_with;
    for (int j = 0; j < m.nq; ++j) a.values.emplace_back(m.joint_name[j], x[2 * m.nq + j]);
  }
  // The partition summary.json and the report record (partition_at_t0): the plan's own under
  // the projection solver, the one that solver would take under the Lagrange solver.
  if (const std::optional<PlannerPartition> part = partition_at_t0(s)) {
    CheckPartition& p = r.partition.emplace();
    for (int j : part->independent) p.independent.push_back(m.joint_name[j]);
    for (int j : part->dependent) p.dependent.push_back(m.joint_name[j]);
    p.automatic = s.automatic_independent;
    p.condition = part->condition;
    p.used_by_solver = solver_uses_partition(s);
  }
  r.solver = resolved_solver(s) == ReferenceSolver::Projection ? "projection" : "lagrange";
  if (s.project_initial && !s.is_jerk_problem()) {  // the projection moves the dependent coordinates
    auto& moved = r.projection.emplace();
    for (int j = 0; j < m.nq; ++j)
      if (s.initial_dq[j] != 0 || s.initial_dqd[j] != 0)
        moved.emplace_back(m.joint_name[j], CheckCorrection{s.initial_dq[j], s.q0[j], s.initial_dqd[j], s.qd0[j]});
  }
  const std::vector<RowResidual> residuals = planner->row_residuals();
  for (int row = 0; row < s.constraints.rows(); ++row) {
    r.residuals.emplace_back(s.constraints.row_name(row), std::vector<std::pair<std::string, double>>{});
    for (const RowResidual& k : residuals) r.residuals.back().second.emplace_back(k.label, k.values[row]);
  }
  const IntegratorOptions& io = s.integrator;
  CheckIntegrator& i = r.integrator;
  i.method = to_string(io.method);
  if (io.method == IntegratorMethod::RK4) {
    i.step = io.step;
  } else {
    i.rtol = io.rtol, i.atol = io.atol;
    if (io.method == IntegratorMethod::BDF) i.max_order = io.max_order;
    i.sample_interval = io.output_interval > 0 ? io.output_interval : io.step;
  }
  i.t0 = t0, i.t1 = io.t1;
  i.stabilization = to_string(s.options.stabilization);
  if (s.options.stabilization != Stabilization::Baumgarte) i.projection_tolerance = s.options.projection_tolerance;
  if (planner->checks_residual_tolerance()) i.residual_tolerance = s.residual_tolerance;
  r.experiments = static_cast<long>(s.experiments.size());
  if (r.experiments > 0) {
    for (int j : s.actuation.actuated) r.plant.actuators.push_back(s.model.joint_name[j]);
    for (int j : s.actuation.independent) r.plant.assigned.push_back(s.model.joint_name[j]);
    r.plant.material_rows = s.material ? s.material->rows() : 0;
  }
  for (const Variant& v : variants) r.variants.push_back(v.name);
  return r;
}

std::string check_text(const CheckReport& r) {
  auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
  };
  std::ostringstream o;  // std::cout's formatting (6 significant digits)
  o << "scenario '" << r.name << "' (" << r.file << "): valid\n" << r.model_summary;
  for (const std::string& n : r.model_notes) o << "  note: " << n << "\n";
  const CheckRows& rows = r.rows;
  o << "constraints: " << r.constraints.size() << " (" << rows.total << " rows)\n";
  for (const CheckReport::Constraint& c : r.constraints)
    o << "  " << c.name << ": " << c.origin << ", " << c.kind << ", " << (c.rheonomic ? "rheonomic" : "scleronomic")
      << ": " << c.description << "\n";
  o << "  rows by kind: " << rows.material << " material, " << rows.programmed << " programmed; " << rows.holonomic
    << " holonomic, " << rows.first_order << " first-order"
    << (rows.acceleration ? ", " + std::to_string(rows.acceleration) + " acceleration-level" : std::string())
    << (rows.jerk ? ", " + std::to_string(rows.jerk) + " jerk-level" : std::string()) << "\n";
  o << "force elements: " << r.force_elements.size();
  for (const std::string& e : r.force_elements) o << "  " << e;
  o << "\n";
  if (!r.planner_description.empty()) o << r.planner_description << "\n";
  if (const auto& a = r.initial_acceleration) {
    o << "initial acceleration at t0 = " << r.t0 << " s"
      << (a->source == "initial.qdd"       ? " (from initial.qdd)"
          : a->source == "consistent_with" ? " (consistent with the acceleration rows of: " + list(a->consistent_with) + ")"
                                           : " (free)")
      << ":";
    for (const auto& [joint, value] : a->values) o << " " << joint << " " << value;
    o << "\n";
  }
  if (const auto& p = r.partition) {
    o << "partition: independent [" << list(p->independent) << "], dependent [" << list(p->dependent) << "]"
      << (p->automatic ? " (chosen automatically)" : "") << "; cond(K_dc) = " << p->condition
      << " at t0 (1-norm: ||A||_1 ||K_dc^-1||_1, A the whole constraint Jacobian)\n";
    if (!p->used_by_solver && r.rows.total == 0)
      o << "  (no constraint rows: nothing to partition)\n";
    else if (!p->used_by_solver && r.solver == "lagrange")
      o << "  (solver lagrange: the KKT solve uses no partition; this is the one solver: projection takes, and "
           "the initial projection's dependent coordinates)\n";
    else if (!p->used_by_solver)
      o << "  (solver projection: at this size its orthonormal null-space solve uses no partition; this is the "
           "initial projection's dependent coordinates)\n";
  }
  if (r.projection) {
    o << "initial state projected onto the constraints (Newton, dependent coordinates):\n";
    for (const auto& [joint, c] : *r.projection)
      o << format("  %-12s q %+.6g -> %.10g   qd %+.6g -> %.10g\n", joint.c_str(), c.dq, c.q, c.dqd, c.qd);
  }
  o << "initial residuals at t0 = " << r.t0 << " s" << (r.projection ? " (after projection)" : "") << ":\n";
  for (const auto& [row, values] : r.residuals) {
    o << format("  %-20s", row.c_str());
    for (size_t k = 0; k < values.size(); ++k)
      o << format("%s%s = %.3e", k ? "   " : " ", values[k].first.c_str(), values[k].second);
    o << "\n";
  }
  const CheckIntegrator& i = r.integrator;
  o << "integrator: " << i.method;
  if (i.step)
    o << ", step " << *i.step << " s";
  else
    o << ", rtol " << i.rtol.value_or(0) << ", atol " << i.atol.value_or(0)
      << (i.max_order ? ", max order " + std::to_string(*i.max_order) : std::string()) << ", samples every "
      << i.sample_interval.value_or(0) << " s";
  o << ", t = [" << i.t0 << ", " << i.t1 << "] s";
  if (i.projection_tolerance)
    o << "; stabilization: " << i.stabilization << " (tolerance " << fmt(*i.projection_tolerance) << ")";
  if (i.residual_tolerance)
    o << "; the plan stops where max |Phi| > "
      << (std::isfinite(*i.residual_tolerance) ? fmt(*i.residual_tolerance) : std::string("(no check)"))
      << " (integrator.residual_tolerance)";
  o << "\n";
  o << "experiments: " << r.experiments << " runs\n";
  if (r.experiments > 0 && (r.plant.material_rows > 0 || r.plant.actuators.size() != r.joints.size()))
    o << "plant: motors at " << list(r.plant.actuators) << "; " << r.plant.material_rows
      << " material rows kept; the controllers assign " << list(r.plant.assigned) << "\n";
  if (!r.variants.empty()) {
    o << "variants: " << r.variants.size() << " (";
    for (size_t k = 0; k < r.variants.size() && k < 3; ++k) o << (k ? ", " : "") << r.variants[k];
    o << (r.variants.size() > 3 ? ", …" : "") << "; each is checked when it is planned)\n";
  }
  return o.str();
}

}  // namespace refdyn::io
