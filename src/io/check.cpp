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
  r.rows = s.constraints.rows();
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
    (c->origin == ConstraintOrigin::Material ? r.material_rows : r.programmed_rows) += c->rows();
    (c->order() == 3 ? r.jerk_rows : c->order() == 2 ? r.acceleration_rows : c->first_order() ? r.first_order_rows
                                                                                                : r.holonomic_rows) +=
        c->rows();
  }
  for (const auto& e : s.forces.elements()) r.force_elements.push_back(e->name());
  r.planner_description = planner->description();
  r.t0 = t0;
  if (planner->state_has_acceleration()) {
    r.has_initial_acceleration = true;
    r.initial_acceleration_given = s.qdd0.size() > 0 || !s.qdd_consistent_with.empty();
    r.initial_acceleration_source =
        s.qdd0.size() ? "initial.qdd" : s.qdd_consistent_with.empty() ? "free" : "consistent_with";
    r.initial_acceleration_rows = s.qdd_consistent_with;
    for (int j = 0; j < m.nq; ++j) r.initial_acceleration.push_back(x[2 * m.nq + j]);
  }
  // The partition summary.json and the report record (partition_at_t0): the plan's own under
  // the projection solver, the one that solver would take under the Lagrange solver.
  if (const std::optional<PlannerPartition> part = partition_at_t0(s)) {
    r.has_partition = true;
    for (int j : part->independent) r.independent.push_back(m.joint_name[j]);
    for (int j : part->dependent) r.dependent.push_back(m.joint_name[j]);
    r.automatic_partition = s.automatic_independent;
    r.condition = part->condition;
    r.partition_used = solver_uses_partition(s);
  }
  r.solver = resolved_solver(s) == ReferenceSolver::Projection ? "projection" : "lagrange";
  r.projected = s.project_initial && !s.is_jerk_problem();  // the projection moves the dependent coordinates
  if (r.projected)
    for (int j = 0; j < m.nq; ++j)
      if (s.initial_dq[j] != 0 || s.initial_dqd[j] != 0)
        r.corrections.push_back({m.joint_name[j], s.initial_dq[j], s.q0[j], s.initial_dqd[j], s.qd0[j]});
  const std::vector<RowResidual> residuals = planner->row_residuals();
  for (const RowResidual& k : residuals) r.residual_labels.push_back(k.label);
  for (int row = 0; row < s.constraints.rows(); ++row) {
    CheckReport::RowResiduals e{s.constraints.row_name(row), {}};
    for (const RowResidual& k : residuals) e.values.push_back(k.values[row]);
    r.residuals.push_back(e);
  }
  const IntegratorOptions& io = s.integrator;
  r.method = to_string(io.method);
  r.step = io.step;
  r.rtol = io.rtol;
  r.atol = io.atol;
  r.max_order = io.max_order;
  r.sample_interval = io.output_interval > 0 ? io.output_interval : io.step;
  r.t1 = io.t1;
  r.stabilization = to_string(s.options.stabilization);
  r.projection_tolerance = s.options.projection_tolerance;
  r.checks_residual = planner->checks_residual_tolerance();
  r.residual_tolerance = s.residual_tolerance;
  r.experiments = static_cast<long>(s.experiments.size());
  if (r.experiments > 0) {
    for (int j : s.actuation.actuated) r.actuators.push_back(s.model.joint_name[j]);
    for (int j : s.actuation.independent) r.plant_independent.push_back(s.model.joint_name[j]);
    r.plant_material_rows = s.material ? s.material->rows() : 0;
  }
  for (const Variant& v : variants) r.variants.push_back(v.name);
  return r;
}

std::string check_text(const CheckReport& r) {
  std::ostringstream o;  // std::cout's formatting (6 significant digits)
  o << "scenario '" << r.name << "' (" << r.file << "): valid\n" << r.model_summary;
  for (const std::string& n : r.model_notes) o << "  note: " << n << "\n";
  o << "constraints: " << r.constraints.size() << " (" << r.rows << " rows)\n";
  for (const CheckReport::Constraint& c : r.constraints)
    o << "  " << c.name << ": " << c.origin << ", " << c.kind << ", " << (c.rheonomic ? "rheonomic" : "scleronomic")
      << ": " << c.description << "\n";
  o << "  rows by kind: " << r.material_rows << " material, " << r.programmed_rows << " programmed; " << r.holonomic_rows
    << " holonomic, " << r.first_order_rows << " first-order"
    << (r.acceleration_rows ? ", " + std::to_string(r.acceleration_rows) + " acceleration-level" : std::string())
    << (r.jerk_rows ? ", " + std::to_string(r.jerk_rows) + " jerk-level" : std::string()) << "\n";
  o << "force elements: " << r.force_elements.size();
  for (const std::string& e : r.force_elements) o << "  " << e;
  o << "\n";
  if (!r.planner_description.empty()) o << r.planner_description << "\n";
  if (r.has_initial_acceleration) {
    std::string rows;
    for (const std::string& name : r.initial_acceleration_rows) rows += (rows.empty() ? "" : ", ") + name;
    o << "initial acceleration at t0 = " << r.t0 << " s"
      << (r.initial_acceleration_source == "initial.qdd" ? " (from initial.qdd)"
          : r.initial_acceleration_source == "consistent_with"
              ? " (consistent with the acceleration rows of: " + rows + ")"
              : " (free)")
      << ":";
    for (size_t j = 0; j < r.joints.size(); ++j) o << " " << r.joints[j] << " " << r.initial_acceleration[j];
    o << "\n";
  }
  if (r.has_partition) {
    o << "partition: independent [";
    for (size_t i = 0; i < r.independent.size(); ++i) o << (i ? ", " : "") << r.independent[i];
    o << "], dependent [";
    for (size_t i = 0; i < r.dependent.size(); ++i) o << (i ? ", " : "") << r.dependent[i];
    o << "]" << (r.automatic_partition ? " (chosen automatically)" : "") << "; cond(K_dc) = " << r.condition
      << " at t0 (1-norm: ||A||_1 ||K_dc^-1||_1, A the whole constraint Jacobian)\n";
    if (!r.partition_used)
      o << "  (solver " << r.solver
        << ": the KKT solve uses no partition; this is the one solver: projection takes, and the initial "
           "projection's dependent coordinates)\n";
  }
  if (r.projected) {
    o << "initial state projected onto the constraints (Newton, dependent coordinates):\n";
    for (const CheckReport::Correction& c : r.corrections)
      o << format("  %-12s q %+.6g -> %.10g   qd %+.6g -> %.10g\n", c.joint.c_str(), c.dq, c.q, c.dqd, c.qd);
  }
  o << "initial residuals at t0 = " << r.t0 << " s" << (r.projected ? " (after projection)" : "") << ":\n";
  for (const CheckReport::RowResiduals& row : r.residuals) {
    o << format("  %-20s", row.row.c_str());
    for (size_t k = 0; k < row.values.size(); ++k)
      o << format("%s%s = %.3e", k ? "   " : " ", r.residual_labels[k].c_str(), row.values[k]);
    o << "\n";
  }
  o << "integrator: " << r.method;
  if (r.method == to_string(IntegratorMethod::RK4))
    o << ", step " << r.step << " s";
  else
    o << ", rtol " << r.rtol << ", atol " << r.atol
      << (r.method == to_string(IntegratorMethod::BDF) ? ", max order " + std::to_string(r.max_order) : std::string())
      << ", samples every " << r.sample_interval << " s";
  o << ", t = [" << r.t0 << ", " << r.t1 << "] s";
  if (r.stabilization != to_string(Stabilization::Baumgarte))
    o << "; stabilization: " << r.stabilization << " (tolerance " << fmt(r.projection_tolerance) << ")";
  if (r.checks_residual)
    o << "; the plan stops where max |Phi| > "
      << (std::isfinite(r.residual_tolerance) ? fmt(r.residual_tolerance) : std::string("(no check)"))
      << " (integrator.residual_tolerance)";
  o << "\n";
  o << "experiments: " << r.experiments << " runs\n";
  if (r.experiments > 0 && (r.plant_material_rows > 0 || r.actuators.size() != r.joints.size())) {
    auto list = [](const std::vector<std::string>& v) {
      std::string s;
      for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
      return s;
    };
    o << "plant: motors at " << list(r.actuators) << "; " << r.plant_material_rows
      << " material rows kept; the controllers assign " << list(r.plant_independent) << "\n";
  }
  if (!r.variants.empty()) {
    o << "variants: " << r.variants.size() << " (";
    for (size_t i = 0; i < r.variants.size() && i < 3; ++i) o << (i ? ", " : "") << r.variants[i];
    o << (r.variants.size() > 3 ? ", …" : "") << "; each is checked when it is planned)\n";
  }
  return o.str();
}

}  // namespace refdyn::io

namespace refdyn {

io::CheckRows Fields<io::CheckReport>::rows(const S& r) {
  return {r.rows, r.material_rows, r.programmed_rows, r.holonomic_rows, r.first_order_rows, r.acceleration_rows,
          r.jerk_rows};
}

std::optional<io::CheckInitialAcceleration> Fields<io::CheckReport>::initial_acceleration(const S& r) {
  if (!r.has_initial_acceleration) return std::nullopt;
  io::CheckInitialAcceleration a;
  for (size_t j = 0; j < r.joints.size() && j < r.initial_acceleration.size(); ++j)
    a.values.emplace_back(r.joints[j], r.initial_acceleration[j]);
  a.source = r.initial_acceleration_source;
  a.consistent_with = r.initial_acceleration_rows;
  return a;
}

std::optional<io::CheckPartition> Fields<io::CheckReport>::partition(const S& r) {
  if (!r.has_partition) return std::nullopt;
  return io::CheckPartition{r.independent, r.dependent, r.automatic_partition, r.condition, r.partition_used};
}

std::optional<std::vector<std::pair<std::string, io::CheckCorrection>>> Fields<io::CheckReport>::projection(
    const S& r) {
  if (!r.projected) return std::nullopt;
  std::vector<std::pair<std::string, io::CheckCorrection>> p;
  for (const io::CheckReport::Correction& c : r.corrections) p.emplace_back(c.joint, io::CheckCorrection{c.dq, c.q, c.dqd, c.qd});
  return p;
}

std::vector<std::pair<std::string, std::vector<std::pair<std::string, double>>>> Fields<io::CheckReport>::residuals(
    const S& r) {
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, double>>>> out;
  for (const io::CheckReport::RowResiduals& row : r.residuals) {
    out.emplace_back(row.row, std::vector<std::pair<std::string, double>>{});
    for (size_t k = 0; k < row.values.size() && k < r.residual_labels.size(); ++k)
      out.back().second.emplace_back(r.residual_labels[k], row.values[k]);
  }
  return out;
}

io::CheckIntegrator Fields<io::CheckReport>::integrator(const S& r) {
  io::CheckIntegrator i;
  i.method = r.method;
  if (r.method == to_string(IntegratorMethod::RK4)) {
    i.step = r.step;
  } else {
    i.rtol = r.rtol, i.atol = r.atol;
    if (r.method == to_string(IntegratorMethod::BDF)) i.max_order = r.max_order;
    i.sample_interval = r.sample_interval;
  }
  i.t0 = r.t0, i.t1 = r.t1;
  i.stabilization = r.stabilization;
  if (r.stabilization != to_string(Stabilization::Baumgarte)) i.projection_tolerance = r.projection_tolerance;
  if (r.checks_residual) i.residual_tolerance = r.residual_tolerance;
  return i;
}

io::CheckPlant Fields<io::CheckReport>::plant(const S& r) {
  return {r.actuators, r.plant_independent, r.plant_material_rows};
}

}  // namespace refdyn
