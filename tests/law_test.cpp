// Each law written once, over a scalar (issue 35): every constraint kind and force element of
// the registries is one template law<S>; evaluate / evaluate_dual, apply / apply_dual, ∂Q/∂q̇ and
// the jerk level's rate are its instantiations. Checked here for every registered kind and
// element, built from one scenario (kEveryLaw) at seeded random states:
//  (1) the scenario covers every registry entry (a new kind must be added here);
//  (2) constraints: the dual values equal the double ones, the dual derivative parts (seeded on
//      q, q̇ and t) equal central differences of the double evaluation;
//  (3) force elements: apply_dual's values equal apply's, its derivative parts (q, q̇, z) and
//      apply's ∂Q/∂q̇ equal central differences, the rate (add_rate_with_states) equals the
//      central difference of Q along the motion (t, q, q̇, z moved by 1, q̇, q̈, ż);
//  (4) the text forms (symbolic(): law<Formula>, formula.hpp; they carry the scenario's
//      parameter names) evaluated by the expression engine equal the laws;
//  (5) capabilities are known at load: a kind without exact derivatives under method: bdf, an
//      element without its rate in a jerk problem, and paper_literal_forces under bdf are refused
//      when the scenario is built, with the entry's location.
//
// FD budget (central, h = 1e-6 (1 + |x|)): truncation h²|f'''|/6 and rounding ε|f|/h stay below
// 1e-9 relative to the block's largest entry for these smooth laws (LuGre with σ0 = 5 and
// Stribeck velocity 0.1: |f'''| ≲ 1e4); the tolerance 1e-6 keeps three orders above both.
#include "refdyn/constraints/law.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/scenario/registry.hpp"
#include "test_support.hpp"

#include "../src/scenario/build.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <set>

using namespace refdyn;
using refdyn::test::near;

namespace {

using JS = JacobianScalar;
constexpr int kDir = kJacobianDirections;

// Every registered constraint kind and force element, on a spatial 5-DOF chain with a base pose,
// a prismatic joint and a non-unit axis; W is fixed at the base pose.
const char* kEveryLaw = R"(name: every_law
parameters: {L: 0.4, R: 0.9, T: 3}
model:
  gravity: [0, 0, -9.81]
  base: {xyz: [0.1, 0, 0.2], rpy: [0, 0, 30*deg]}
  links:
    - {name: l1, joint: j1, parent: base, type: revolute, axis: [0, 0, 1], mass: 1.5, com: [0, 0, L/2], inertia: [0.02, 0.02, 0.01]}
    - {name: l2, joint: j2, parent: l1, type: revolute, axis: [0, 1, 0], origin: {xyz: [0, 0, L]}, mass: 1.2, com: [L/2, 0, 0], inertia: [0.01, 0.03, 0.03]}
    - {name: l3, joint: j3, parent: l2, type: prismatic, axis: [1, 0, 0], origin: {xyz: [L, 0, 0]}, mass: 0.8, com: [0.1, 0, 0], inertia: [0.002, 0.01, 0.01]}
    - {name: l4, joint: j4, parent: l3, type: revolute, axis: [1, 1, 0], origin: {xyz: [0.2, 0, 0]}, mass: 0.5, com: [0.05, 0, 0], inertia: [0.001, 0.002, 0.002]}
    - {name: l5, joint: j5, parent: l4, type: revolute, axis: [0, 0, 1], mass: 0.2, com: [0.03, 0, 0], inertia: [0.0005, 0.0005, 0.0005]}
  points:
    E: {link: l5, position: [0.1, 0, 0]}
    F: {link: l3, position: [0.05, 0.02, 0.01]}
    W: {link: base, position: [0.5, 0.5, 0.0]}
constraints:
  - {name: ell, kind: point_on_ellipse, point: E, a: 0.5, b: 0.3, center: [0.1, -0.05]}
  - {name: sph, kind: point_on_sphere, point: F, center: [0.1, 0.0, 0.2], radius: 0.6}
  - {name: coord, kind: point_coordinate, point: E, axis: z, function: 0.3 + 0.1*sin(1.3*t + 0.2)}
  - {name: traj, kind: joint_trajectory, joint: j1, function: {cycloidal: {rise: 1, duration: 2}}}
  - {name: gear, kind: joint_coupling, joint: j5, leader: j4, ratio: 0.5, offset: 0.1}
  - {name: loop, kind: points_coincide, points: [E, F], axes: [x, y]}
  - {name: edge, kind: knife_edge, point: E, lateral_axis: [0, 1, 0.5]}
  - {name: speed, kind: point_speed, point: F, direction: [1, 0.5, 0], speed: {raised_cosine: {base: 0, amplitude: 0.2, period: T}}}
  - {name: reach, kind: distance, points: [E, W], length: {raised_cosine: {base: R, amplitude: 0.05, period: T}}}
  - {name: e0, expression: (x(E) - 0.1)^2 + sin(q(j2))*y(F) - 0.3 + 0.1*t}
  - {name: e1, order: velocity, expression: x(E)*vy(E) - y(E)*vx(E) + 0.2*qd(j3) - 0.05*t}
  - {name: e2, order: acceleration, expression: ax(E) + cos(q(j1))*qdd(j2) + vx(F)^2 - 0.1*t}
forces:
  - {type: spring, joint: j1, stiffness: 20, rest: 0.2}
  - {type: damping, joint: j2, coefficient: 0.3}
  - {type: effort, joint: j3, value: {cycloidal: {rise: 2, duration: T}}}
  - {type: lugre, joint: j4, mu_s: 0.1, mu_k: 0.2, sigma0: 5, sigma1: 0.02, sigma2: 0.01, stribeck_velocity: 0.1}
  - {type: flexible_drive, joint: j5, stiffness: 1e4, damping: 70, profile: {cycloidal: {rise: 6, duration: 5}}}
initial:
  q: {j1: 0.3, j2: 0.4, j3: 0.1, j4: 0.5, j5: 0.25}
  qd: {j1: 0, j2: 0, j3: 0, j4: 0, j5: 0}
integrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.01}
)";

const std::map<std::string, double> kParams = {{"L", 0.4}, {"R", 0.9}, {"T", 3.0}, {"deg", M_PI / 180}};

/// The scenario's model and forces (built by build_problem) and its constraints, each built by
/// its registry entry without the t0 checks (twelve rows on five coordinates).
struct EveryLaw {
  ScenarioSpec spec;
  std::unique_ptr<Problem> problem;
  std::vector<ConstraintPtr> constraints;
  std::vector<std::string> kinds;  ///< the registry name of each constraint
};

const EveryLaw& every_law() {
  static const EveryLaw e = [] {
    EveryLaw r;
    r.spec = io::parse_scenario(kEveryLaw, "every_law.yaml");
    ScenarioSpec without = r.spec;
    without.constraints.clear();
    r.problem = build_problem(without);
    const SpecReader reader("every_law.yaml", kParams);
    for (const EntrySpec& entry : r.spec.constraints) {
      NewConstraint c = constraint_kinds().get(entry.kind).build(EntryArgs{reader, entry, r.problem->model},
                                                                 ConstraintOrigin::Programmed);
      c->name = entry.name;
      r.constraints.push_back(c);
      r.kinds.push_back(entry.kind);
    }
    return r;
  }();
  return e;
}

struct State {
  double t;
  Eigen::VectorXd q, qd, qdd, z, zd;
};
State random_state(std::mt19937& rng, int n, int nz) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  State s{1.0 + u(rng), test::random_vector(rng, n, 1.2), test::random_vector(rng, n, 0.8),
          test::random_vector(rng, n, 2.0), test::random_vector(rng, std::max(1, nz), 1e-3),
          test::random_vector(rng, std::max(1, nz), 0.1)};
  return s;
}

double step_for(double x) { return 1e-6 * (1.0 + std::abs(x)); }

/// Central-difference tolerance for a block: relative 1e-6 with a floor of 1e-6 × its largest entry.
::testing::AssertionResult fd_near(const Eigen::MatrixXd& exact, const Eigen::MatrixXd& fd) {
  const double scale = std::max({1.0, exact.cwiseAbs().maxCoeff(), fd.cwiseAbs().maxCoeff()});
  return near(exact, fd, 1e-6, 1e-6 * scale);
}

// ---------------------------------------------------------------------------------------------
// (1) coverage
// ---------------------------------------------------------------------------------------------
TEST(EveryLaw, CoversEveryRegisteredKindAndElement) {
  const EveryLaw& e = every_law();
  const std::set<std::string> kinds(e.kinds.begin(), e.kinds.end());
  for (const std::string& k : constraint_kinds().names()) EXPECT_TRUE(kinds.count(k)) << "constraint kind " << k;
  std::set<std::string> types;
  for (const EntrySpec& f : e.spec.forces) types.insert(f.kind);
  for (const std::string& k : force_kinds().names()) EXPECT_TRUE(types.count(k)) << "force element " << k;
}

// ---------------------------------------------------------------------------------------------
// (2) constraint kinds: double, dual, central differences
// ---------------------------------------------------------------------------------------------
struct Rows {
  Eigen::VectorXd phi, phid, gamma;
  Eigen::MatrixXd A;
  Eigen::VectorXd flat() const {
    Eigen::VectorXd f(phi.size() * 3 + A.size());
    f << phi, phid, gamma, Eigen::Map<const Eigen::VectorXd>(A.data(), A.size());
    return f;
  }
};

Rows eval_double(const Model& m, const ConstraintSet& set, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  Data data(m);
  ConstraintEval ev(m, set);
  evaluate_constraints(m, data, set, ev, t, q, qd);
  return {ev.phi, ev.phid, ev.gamma, ev.A};
}

TEST(ConstraintLaw, EveryKindsDualEqualsItsDoubleAndCentralDifferences) {
  const EveryLaw& e = every_law();
  const Model& m = e.problem->model;
  const int n = m.nv, nd = 2 * n + 1;  // directions: q_j, q̇_j, t
  std::mt19937 rng(351);
  for (size_t k = 0; k < e.constraints.size(); ++k) {
    ConstraintSet set;
    set.add(e.constraints[k]);
    ConstraintEvalDual ev(m, set);
    const int rows = set.rows();
    for (int trial = 0; trial < 12; ++trial) {
      const State s = random_state(rng, n, 0);
      const Rows d = eval_double(m, set, s.t, s.q, s.qd);
      const Eigen::VectorXd f0 = d.flat();
      Eigen::MatrixXd exact(f0.size(), nd), fd(f0.size(), nd);
      for (int c0 = 0; c0 < nd; c0 += kDir) {
        std::vector<JS> q(n), qd(n);
        JS t(s.t);
        for (int i = 0; i < n; ++i) q[i] = JS(s.q[i]), qd[i] = JS(s.qd[i]);
        for (int c = c0; c < std::min(nd, c0 + kDir); ++c) {
          if (c < n) q[c].d[c - c0] = 1.0;
          else if (c < 2 * n) qd[c - n].d[c - c0] = 1.0;
          else t.d[c - c0] = 1.0;
        }
        evaluate_constraints_dual(m, set, ev, t, q.data(), qd.data());
        Eigen::VectorXd value(f0.size());
        for (int c = c0; c < std::min(nd, c0 + kDir); ++c) {
          for (int r = 0; r < rows; ++r) {
            value[r] = ev.phi[r].v, value[rows + r] = ev.phid[r].v, value[2 * rows + r] = ev.gamma[r].v;
            exact(r, c) = ev.phi[r].d[c - c0];
            exact(rows + r, c) = ev.phid[r].d[c - c0];
            exact(2 * rows + r, c) = ev.gamma[r].d[c - c0];
            for (int j = 0; j < n; ++j) {
              value[3 * rows + j * rows + r] = ev.A[r * n + j].v;
              exact(3 * rows + j * rows + r, c) = ev.A[r * n + j].d[c - c0];
            }
          }
        }
        EXPECT_TRUE(near(value, f0, 1e-13, 1e-14)) << e.kinds[k] << " '" << set.row_name(0) << "': dual values";
      }
      for (int c = 0; c < nd; ++c) {
        Eigen::VectorXd qp = s.q, qm = s.q, qdp = s.qd, qdm = s.qd;
        double tp = s.t, tm = s.t, h;
        if (c < n) h = step_for(s.q[c]), qp[c] += h, qm[c] -= h;
        else if (c < 2 * n) h = step_for(s.qd[c - n]), qdp[c - n] += h, qdm[c - n] -= h;
        else h = step_for(s.t), tp += h, tm -= h;
        fd.col(c) = (eval_double(m, set, tp, qp, qdp).flat() - eval_double(m, set, tm, qm, qdm).flat()) / (2 * h);
      }
      EXPECT_TRUE(fd_near(exact, fd)) << e.kinds[k] << " '" << set.row_name(0) << "' trial " << trial;
      // The law's own identities, by central differences along the motion (q, q̇, t moved by
      // q̇, q̈, 1): holonomic rows dΦ/dt = Φ̇, dΦ̇/dt = A q̈ + γ, A = ∂Φ/∂q; first-order rows
      // dc/dt = A q̈ + γ, A = ∂c/∂q̇ (acceleration rows have Φ = Φ̇ = 0: nothing to check).
      const double h = 1e-6;
      const Rows p = eval_double(m, set, s.t + h, s.q + h * s.qd, s.qd + h * s.qdd);
      const Rows mo = eval_double(m, set, s.t - h, s.q - h * s.qd, s.qd - h * s.qdd);
      const Eigen::VectorXd Aqdd_gamma = d.A * s.qdd + d.gamma;
      const Eigen::MatrixXd dphi_dq = fd.block(0, 0, rows, n), dphi_dqd = fd.block(0, n, rows, n);
      for (int r = 0; r < rows; ++r) {
        const int order = set.row_order(r);
        if (order == 2) continue;
        const double dphi = (p.phi[r] - mo.phi[r]) / (2 * h), dphid = (p.phid[r] - mo.phid[r]) / (2 * h);
        const Eigen::MatrixXd A = d.A.row(r);
        if (order == 0) {
          EXPECT_TRUE(fd_near(Eigen::VectorXd::Constant(1, d.phid[r]), Eigen::VectorXd::Constant(1, dphi)))
              << e.kinds[k] << " row " << r << ": dPhi/dt = Phid";
          EXPECT_TRUE(fd_near(Eigen::VectorXd::Constant(1, Aqdd_gamma[r]), Eigen::VectorXd::Constant(1, dphid)))
              << e.kinds[k] << " row " << r << ": dPhid/dt = A qdd + gamma";
          EXPECT_TRUE(fd_near(A, dphi_dq.row(r))) << e.kinds[k] << " row " << r << ": A = dPhi/dq";
        } else {
          EXPECT_TRUE(fd_near(Eigen::VectorXd::Constant(1, Aqdd_gamma[r]), Eigen::VectorXd::Constant(1, dphi)))
              << e.kinds[k] << " row " << r << ": dc/dt = A qdd + gamma";
          EXPECT_TRUE(fd_near(A, dphi_dqd.row(r))) << e.kinds[k] << " row " << r << ": A = dc/dqd";
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (3) force elements: apply, apply_dual, ∂Q/∂q̇, the rate
// ---------------------------------------------------------------------------------------------
struct ForceOut {
  Eigen::VectorXd Q, zdot;
};
ForceOut apply(const ForceElement& f, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
               const Eigen::VectorXd& z, Eigen::MatrixXd* dQ = nullptr) {
  ForceOut o{Eigen::VectorXd::Zero(q.size()), Eigen::VectorXd::Zero(std::max(1, f.num_states()))};
  f.apply(t, q, qd, z.data(), o.Q, o.zdot.data(), dQ);
  o.zdot.conservativeResize(f.num_states());
  return o;
}

TEST(ForceLaw, EveryElementsDualJacobianAndRateEqualCentralDifferences) {
  const EveryLaw& e = every_law();
  const Model& m = e.problem->model;
  const int n = m.nv;
  std::mt19937 rng(352);
  for (const ForceElementPtr& fp : e.problem->forces.elements()) {
    const ForceElement& f = *fp;
    const int nz = f.num_states(), nd = 2 * n + nz;  // directions: q_j, q̇_j, z_k
    for (int trial = 0; trial < 12; ++trial) {
      const State s = random_state(rng, n, nz);
      const ForceOut o = apply(f, s.t, s.q, s.qd, s.z);
      // dual: values and derivative parts
      Eigen::MatrixXd exact(n + nz, nd), fd(n + nz, nd);
      for (int c0 = 0; c0 < nd; c0 += kDir) {
        std::vector<JS> q(n), qd(n), z(std::max(1, nz)), Q(n, JS(0.0)), zdot(std::max(1, nz));
        for (int i = 0; i < n; ++i) q[i] = JS(s.q[i]), qd[i] = JS(s.qd[i]);
        for (int i = 0; i < nz; ++i) z[i] = JS(s.z[i]);
        for (int c = c0; c < std::min(nd, c0 + kDir); ++c) {
          if (c < n) q[c].d[c - c0] = 1.0;
          else if (c < 2 * n) qd[c - n].d[c - c0] = 1.0;
          else z[c - 2 * n].d[c - c0] = 1.0;
        }
        f.apply_dual(s.t, q.data(), qd.data(), z.data(), Q.data(), zdot.data());
        for (int i = 0; i < n; ++i) EXPECT_NEAR(Q[i].v, o.Q[i], 1e-14 * (1 + std::abs(o.Q[i]))) << f.name();
        for (int i = 0; i < nz; ++i) EXPECT_NEAR(zdot[i].v, o.zdot[i], 1e-14 * (1 + std::abs(o.zdot[i]))) << f.name();
        for (int c = c0; c < std::min(nd, c0 + kDir); ++c) {
          for (int i = 0; i < n; ++i) exact(i, c) = Q[i].d[c - c0];
          for (int i = 0; i < nz; ++i) exact(n + i, c) = zdot[i].d[c - c0];
        }
      }
      for (int c = 0; c < nd; ++c) {
        Eigen::VectorXd qp = s.q, qm = s.q, qdp = s.qd, qdm = s.qd, zp = s.z, zm = s.z;
        double h;
        if (c < n) h = step_for(s.q[c]), qp[c] += h, qm[c] -= h;
        else if (c < 2 * n) h = step_for(s.qd[c - n]), qdp[c - n] += h, qdm[c - n] -= h;
        else h = 1e-9, zp[c - 2 * n] += h, zm[c - 2 * n] -= h;
        const ForceOut p = apply(f, s.t, qp, qdp, zp), mo = apply(f, s.t, qm, qdm, zm);
        fd.col(c) << (p.Q - mo.Q) / (2 * h), (p.zdot - mo.zdot) / (2 * h);
      }
      EXPECT_TRUE(fd_near(exact, fd)) << f.name() << " trial " << trial;
      // ∂Q/∂q̇ of apply (the paper-literal option) is the q̇ block of the dual sweep, added to dQ
      Eigen::MatrixXd dQ = Eigen::MatrixXd::Constant(n, n, 0.25);
      apply(f, s.t, s.q, s.qd, s.z, &dQ);
      EXPECT_TRUE(near(dQ - Eigen::MatrixXd::Constant(n, n, 0.25), exact.block(0, n, n, n), 1e-15, 1e-15)) << f.name();
      // the rate along the motion: t + h, q + h q̇, q̇ + h q̈, z + h ż
      Eigen::VectorXd rate = Eigen::VectorXd::Zero(n);
      ASSERT_TRUE(f.add_rate_with_states(s.t, s.q, s.qd, s.qdd, s.z.data(), s.zd.data(), rate)) << f.name();
      const double h = 1e-6;
      const ForceOut p = apply(f, s.t + h, s.q + h * s.qd, s.qd + h * s.qdd, s.z + h * s.zd);
      const ForceOut mo = apply(f, s.t - h, s.q - h * s.qd, s.qd - h * s.qdd, s.z - h * s.zd);
      EXPECT_TRUE(fd_near(rate, (p.Q - mo.Q) / (2 * h))) << f.name() << " rate, trial " << trial;
      Eigen::VectorXd without = Eigen::VectorXd::Zero(n);
      EXPECT_EQ(f.add_rate(s.t, s.q, s.qd, s.qdd, without), nz == 0) << f.name() << ": add_rate needs the states' rates";
      if (nz == 0) EXPECT_TRUE(near(without, rate, 0, 0)) << f.name();
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (4) the text forms against the laws
// ---------------------------------------------------------------------------------------------
/// Names and values of the variables a text may use (symbolic_form.hpp): t, q, qd, qdd per
/// joint; x, y, z, vx, vy, vz, ax, ay, az and R11 … R33 per point.
struct Variables {
  std::vector<std::string> names;
  std::vector<double> values;
  void add(const std::string& n, double v) {
    names.push_back(n);
    values.push_back(v);
  }
};

double evaluate_text(const std::string& text, const Variables& v, std::map<std::string, double> params) {
  const Expression x(text, v.names, params, 0);
  return x.value(v.values.data());
}

TEST(SymbolicForms, EveryKindsTextEqualsItsLaw) {
  const EveryLaw& e = every_law();
  const Model& m = e.problem->model;
  const int n = m.nv;
  std::mt19937 rng(353);
  for (size_t k = 0; k < e.constraints.size(); ++k) {
    const Constraint& c = *e.constraints[k];
    const std::optional<SymbolicForm> form = c.symbolic(m);
    ASSERT_TRUE(form) << e.kinds[k] << " has no text form";
    ConstraintSet set;
    set.add(e.constraints[k]);
    ASSERT_EQ(static_cast<int>(form->rows.size()), set.rows()) << e.kinds[k];
    std::map<std::string, double> params = form->parameters;
    if (form->scenario_texts) params.insert(kParams.begin(), kParams.end());
    for (int trial = 0; trial < 5; ++trial) {
      const State s = random_state(rng, n, 0);
      Data data(m);
      ConstraintEval ev(m, set);
      std::vector<int> all(m.point_name.size());
      for (size_t p = 0; p < all.size(); ++p) all[p] = static_cast<int>(p);
      evaluate_constraints(m, data, set, ev, s.t, s.q, s.qd);
      std::vector<PointState> points(m.point_name.size(), ev.points[0]);
      forward_kinematics(m, data, s.q);
      compute_point_states(m, data, all, s.qd, points);
      Variables v;
      v.add("t", s.t);
      for (int j = 0; j < n; ++j) {
        v.add("q(" + m.joint_name[j] + ")", s.q[j]);
        v.add("qd(" + m.joint_name[j] + ")", s.qd[j]);
        v.add("qdd(" + m.joint_name[j] + ")", s.qdd[j]);
      }
      for (size_t p = 0; p < points.size(); ++p) {
        const std::string P = "(" + m.point_name[p] + ")";
        const Vec3 a = points[p].d + points[p].C * s.qdd;
        for (int i = 0; i < 3; ++i) {
          const std::string x(1, "xyz"[i]);
          v.add(x + P, points[p].r[i]);
          v.add("v" + x + P, points[p].v[i]);
          v.add("a" + x + P, a[i]);
          for (int j = 0; j < 3; ++j) v.add("R" + std::to_string(i + 1) + std::to_string(j + 1) + P, points[p].R(i, j));
        }
      }
      // order 0: Φ; order 1: c; order 2: B q̈ + s = A q̈ + γ
      const Eigen::VectorXd law = c.order() == 2 ? Eigen::VectorXd(ev.A * s.qdd + ev.gamma) : ev.phi;
      for (int r = 0; r < set.rows(); ++r) {
        const double text = evaluate_text(form->rows[r], v, params);
        EXPECT_NEAR(text, law[r], 1e-12 * (1 + std::abs(law[r]))) << e.kinds[k] << ": " << form->rows[r];
      }
    }
  }
}

TEST(SymbolicForms, EveryElementsTextEqualsItsLaw) {
  const EveryLaw& e = every_law();
  const Model& m = e.problem->model;
  const int n = m.nv;
  std::mt19937 rng(354);
  for (const ForceElementPtr& fp : e.problem->forces.elements()) {
    const ForceElement& f = *fp;
    const std::optional<SymbolicForm> form = f.symbolic(m);
    ASSERT_TRUE(form) << f.name() << " has no text form";
    std::map<std::string, double> params = form->parameters;
    if (form->scenario_texts) params.insert(kParams.begin(), kParams.end());
    const int nz = f.num_states();
    for (int trial = 0; trial < 5; ++trial) {
      const State s = random_state(rng, n, nz);
      const ForceOut o = apply(f, s.t, s.q, s.qd, s.z);
      Variables v;
      v.add("t", s.t);
      for (int j = 0; j < n; ++j) {
        v.add("q(" + m.joint_name[j] + ")", s.q[j]);
        v.add("qd(" + m.joint_name[j] + ")", s.qd[j]);
      }
      for (int i = 0; i < nz; ++i) {
        v.add("z(" + std::to_string(i) + ")", s.z[i]);
        v.add("zdot(" + std::to_string(i) + ")", o.zdot[i]);
      }
      for (const auto& [name, text] : form->functions) {  // a named function of t and its derivative
        const Expression g(text, {"t"}, params, 1);
        double value = 0, slope = 0;
        g.evaluate(&s.t, value, &slope, nullptr);
        v.add(name, value);
        v.add("d_" + name, slope);
      }
      ASSERT_EQ(static_cast<int>(form->state_rates.size()), nz) << f.name();
      for (int i = 0; i < nz; ++i)
        EXPECT_NEAR(evaluate_text(form->state_rates[i], v, params), o.zdot[i], 1e-12 * (1 + std::abs(o.zdot[i])))
            << f.name() << ": " << form->state_rates[i];
      ASSERT_EQ(form->rows.size(), form->joints.size()) << f.name();
      Eigen::VectorXd Q = Eigen::VectorXd::Zero(n);
      for (size_t r = 0; r < form->rows.size(); ++r) Q[form->joints[r]] += evaluate_text(form->rows[r], v, params);
      EXPECT_TRUE(near(Q, o.Q, 1e-12, 1e-12)) << f.name();
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (5) capabilities known at load
// ---------------------------------------------------------------------------------------------
TEST(Capabilities, EveryBuiltInKindAndElementHasExactDerivativesAndRates) {
  const EveryLaw& e = every_law();
  for (size_t k = 0; k < e.constraints.size(); ++k) EXPECT_TRUE(e.constraints[k]->exact_derivatives()) << e.kinds[k];
  for (const ForceElementPtr& f : e.problem->forces.elements()) {
    EXPECT_TRUE(f->exact_derivatives()) << f->name();
    EXPECT_TRUE(f->has_rate()) << f->name();
  }
}

const char* kBdf = R"(name: capabilities
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: l1, joint: j1, parent: base, type: revolute, axis: [0, 0, 1], mass: 1, com: [0.1, 0, 0], inertia: [0.01, 0.01, 0.01]}
    - {name: l2, joint: j2, parent: l1, type: revolute, axis: [0, 1, 0], origin: {xyz: [0.3, 0, 0]}, mass: 1, com: [0.1, 0, 0], inertia: [0.01, 0.01, 0.01]}
constraints:
  - {name: follow, kind: joint_trajectory, joint: j1, function: 0.1*t}
forces:
  - {type: damping, joint: j2, coefficient: 0.2}
initial:
  q: {j1: 0, j2: 0.3}
  qd: {j1: 0.1, j2: 0}
integrator: {method: bdf, step: 1e-3, t0: 0, t1: 0.1}
)";

/// A hand-written kind without evaluate_dual (Constraint's defaults) and an element without
/// apply_dual or a rate (ForceElement's defaults).
class HandWrittenKind final : public Constraint {
 public:
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    phi[0] = in.q[0] - 0.1 * in.t;
    phid[0] = in.qd[0] - 0.1;
    A.row(0).setZero();
    A(0, 0) = 1;
    gamma[0] = 0;
  }
  std::string describe() const override { return "a hand-written kind"; }
};
class HandWrittenElement final : public ForceElement {
 public:
  std::string name() const override { return "push"; }
  void apply(double, const Eigen::VectorXd&, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
             Eigen::MatrixXd*) const override {
    Q[1] += 0.1;
  }
};

TEST(Capabilities, ScenarioBuildsWithTheBuiltInKinds) {
  EXPECT_NO_THROW(io::parse_problem(kBdf, "capabilities.yaml"));
}

TEST(Capabilities, BdfRefusesAKindOrElementWithoutExactDerivativesAtLoadWithItsLocation) {
  const ScenarioSpec spec = io::parse_scenario(kBdf, "capabilities.yaml");
  std::unique_ptr<Problem> p = build_problem(spec);
  const SpecReader reader("capabilities.yaml", {});
  EXPECT_NO_THROW(build::check_capabilities(reader, spec, *p));
  {
    auto hand = std::make_shared<HandWrittenKind>();
    hand->name = "follow";
    p->constraints = ConstraintSet();
    p->constraints.add(hand);
    test::expect_error_mentioning([&] { build::check_capabilities(reader, spec, *p); },
                                  {"capabilities.yaml:8: constraints.follow:", "constraint 'follow'",
                                   "no exact derivatives (evaluate_dual)", "method: bdf", "method: rk4 or dopri5"});
  }
  {
    ForceSet forces;
    forces.add(std::make_shared<HandWrittenElement>());
    test::expect_error_mentioning([&] { build::check_force_capabilities(reader, spec.forces, forces, true, false); },
                                  {"capabilities.yaml:10: forces[0]:", "force element 'push'",
                                   "no exact derivatives (apply_dual)", "method: bdf"});
    // the jerk level asks for the element's rate
    test::expect_error_mentioning([&] { build::check_force_capabilities(reader, spec.forces, forces, false, true); },
                                  {"capabilities.yaml:10: forces[0]:", "force element 'push'", "jerk constraints",
                                   "time derivative of every force"});
  }
}

TEST(Capabilities, PaperLiteralForcesUnderBdfAreRefusedAtLoad) {
  const std::string yaml = std::string(kBdf) + "paper_literal_forces: true\n";
  test::expect_error_mentioning([&] { io::parse_problem(yaml, "capabilities.yaml"); },
                                {"capabilities.yaml:14: integrator.method:", "paper_literal_forces: true",
                                 "method: rk4 or dopri5"});
}

}  // namespace
