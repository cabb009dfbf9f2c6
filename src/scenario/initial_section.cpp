// The initial-state section of build_problem (build.hpp): initial q0, q̇0 (and q̈0 for jerk
// problems) as written, projected onto the constraints when asked, and the checks at t0 (every
// row finite and independent, the partition chosen, forces and constraints finite).
#include "build.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace refdyn::build {

namespace {

/// The rows of `set` evaluated at the initial state into `ev`; an evaluation error is located at
/// the constraints section.
void evaluate_at_t0(const SpecReader& c, const ScenarioSpec& spec, const Model& m, Data& data, const ConstraintSet& set,
                    ConstraintEval& ev, double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0) {
  try {
    evaluate_constraints(m, data, set, ev, t0, q0, qd0);
  } catch (const Error& e) {
    c.fail(spec.constraints_value, "constraints", std::string("at t0 = ") + fmt(t0) + " s: " + e.what());
  }
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
  evaluate_at_t0(c, spec, m, data, cs, ev, t0, p.q0, p.qd0);
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

}  // namespace

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
      evaluate_at_t0(c, spec, m, data, lower, ev, t0, s.q0, s.qd0);
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

}  // namespace refdyn::build
