// Programmed constraints of order p = 2 (acceleration level, B(t, q, q̇) q̈ + s = 0), see
// docs/higher_order.md:
//  - the constraint's B and s against finite differences of the point kinematics;
//  - (a) a position constraint differentiated twice and imposed at the acceleration level, with
//    consistent initial conditions, gives the position-level plan's motion, with RK4's order 4;
//  - (b) a closed form: a particle in polar coordinates whose tangential acceleration is
//    prescribed moves on a straight line with s̈ = a_t(t), and the reaction is m a_t along the
//    path; RK4's order 4 measured;
//  - the projection and the Lagrange (KKT) routes agree; bad inputs are rejected by name.
// Order p = 3 (jerk) is tested in tests/jerk_test.cpp.
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

using namespace refdyn;

namespace {

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (size_t pos; (pos = s.find(from)) != std::string::npos;) s.replace(pos, from.size(), to);
  return s;
}

std::string num(double x) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", x);
  return b;
}

// ---------------------------------------------------------------------------------------------
// A planar 2R arm in the vertical plane (gravity −y) with damping in both joints.
const char* kArm = R"(
name: arm
parameters:
  L1: 0.5
  L2: 0.4
  m1: 2.0
  m2: 1.5
  q10: 0.3
  q20: 1.1
  w: 2.5                       # rate of the height profile [rad/s]
  h: 0.12                      # height change [m]
  y0: L1*sin(q10) + L2*sin(q10 + q20)
  qd10: 0.6                    # consistent: vy(E) = 0 at t0
  qd20: -qd10 - L1*cos(q10)*qd10/(L2*cos(q10 + q20))
model:
  gravity: [0, -9.81, 0]
  links:
    - {name: upper, joint: q1, parent: base, type: revolute, axis: [0, 0, 1],
       mass: m1, com: [L1/2, 0, 0], inertia: [0.001, m1*L1^2/12, m1*L1^2/12]}
    - {name: fore, joint: q2, parent: upper, type: revolute, axis: [0, 0, 1], origin: {xyz: [L1, 0, 0]},
       mass: m2, com: [L2/2, 0, 0], inertia: [0.001, m2*L2^2/12, m2*L2^2/12]}
  points:
    E: {link: fore, position: [L2, 0, 0]}
forces:
  - {type: damping, joint: q1, coefficient: 0.3}
  - {type: damping, joint: q2, coefficient: 0.2}
constraints:
@CONSTRAINT@
partition: {independent: [q1]}
@SOLVER@
initial:
  q: {q1: q10, q2: q20}
  qd: {q1: qd10, q2: qd20}
integrator: {method: rk4, step: @STEP@, t0: 0, t1: 2}
)";

// E's height follows y0 + h (1 − cos wt)/2: at the position level, and differentiated twice.
const char* kHeightPosition = R"(  - name: height
    expression: y(E) - (y0 + h*(1 - cos(w*t))/2))";
const char* kHeightAcceleration = R"(  - name: height
    order: acceleration
    expression: ay(E) - h*w^2*cos(w*t)/2)";

std::unique_ptr<Problem> arm(const char* constraint, double step, const std::string& solver = "") {
  std::string y = replace_all(kArm, "@CONSTRAINT@", constraint);
  y = replace_all(y, "@STEP@", num(step));
  y = replace_all(y, "@SOLVER@", solver.empty() ? "" : "solver: " + solver);
  return io::parse_problem(y, "arm.yaml");
}

Plan plan_of(const Problem& p) {
  auto rd = p.make_reference_dynamics();
  Plan plan = plan_problem(p, *rd);
  EXPECT_TRUE(plan.summary.ok()) << plan.summary.message;
  return plan;
}

/// q at the last sample (t1).
Eigen::VectorXd final_q(const Plan& plan) { return plan.x.back().head(plan.nq()); }

// ---------------------------------------------------------------------------------------------
TEST(AccelerationConstraint, BAndSMatchFiniteDifferencesOfThePointKinematics) {
  const auto p = arm(kHeightPosition, 1e-3);  // only for the model
  const Model& m = p->model;
  // Every kind of variable: point position, velocity, acceleration, joint q, qd, qdd, t.
  const std::string text =
      "x(E)*ax(E) + (2 + sin(q(q1)))*qdd(q2) + t*vy(E)*ay(E) - qd(q1)^2*qdd(q1) + qd(q2)*x(E) - cos(3*t)";
  ConstraintSet cs;
  cs.add(expression_constraint(m, "c", text, ConstraintOrder::Acceleration));
  EXPECT_EQ(cs.row_order(0), 2);
  EXPECT_FALSE(cs.row_first_order(0));

  // Position and velocity of E through a holonomic probe: Φ = x(E) gives Φ̇ = vx(E).
  ConstraintSet probe;
  probe.add(expression_constraint(m, "px", "x(E)", false));
  probe.add(expression_constraint(m, "py", "y(E)", false));
  Data data(m);
  ConstraintEval pe(m, probe);
  auto point_pv = [&](const Eigen::VectorXd& q, const Eigen::VectorXd& qd, Eigen::Vector2d& r, Eigen::Vector2d& v) {
    evaluate_constraints(m, data, probe, pe, 0.0, q, qd);
    r = pe.phi;
    v = pe.phid;
  };

  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = test::random_vector(rng, 2, 1.5), qd = test::random_vector(rng, 2, 2.0),
                          qdd = test::random_vector(rng, 2, 3.0);
    const double t = 0.37 * (trial + 1);
    ConstraintEval ev(m, cs);
    evaluate_constraints(m, data, cs, ev, t, q, qd);
    EXPECT_EQ(ev.phi[0], 0.0);
    EXPECT_EQ(ev.phid[0], 0.0);
    // Point acceleration by central differences along q(τ) = q + q̇τ + q̈τ²/2.
    const double e = 1e-5;
    Eigen::Vector2d r, v, rp, vp, rm, vm;
    point_pv(q, qd, r, v);
    point_pv(q + qd * e + 0.5 * qdd * e * e, qd + qdd * e, rp, vp);
    point_pv(q - qd * e + 0.5 * qdd * e * e, qd - qdd * e, rm, vm);
    const Eigen::Vector2d a = (vp - vm) / (2 * e);
    const double direct = r.x() * a.x() + (2 + std::sin(q[0])) * qdd[1] + t * v.y() * a.y() -
                          qd[0] * qd[0] * qdd[0] + qd[1] * r.x() - std::cos(3 * t);
    const double from_b_s = ev.A.row(0).dot(qdd) + ev.gamma[0];
    EXPECT_NEAR(from_b_s, direct, 1e-7 * (1 + std::abs(direct))) << "trial " << trial;
    // B = ∂f/∂q̈ by differences in q̈ (f is affine in q̈: exact up to rounding).
    for (int j = 0; j < 2; ++j) {
      Eigen::VectorXd dq = Eigen::VectorXd::Zero(2);
      dq[j] = 1.0;
      point_pv(q + qd * e + 0.5 * (qdd + dq) * e * e, qd + (qdd + dq) * e, rp, vp);
      point_pv(q - qd * e + 0.5 * (qdd + dq) * e * e, qd - (qdd + dq) * e, rm, vm);
      const Eigen::Vector2d a2 = (vp - vm) / (2 * e);
      const double direct2 = r.x() * a2.x() + (2 + std::sin(q[0])) * (qdd[1] + dq[1]) + t * v.y() * a2.y() -
                             qd[0] * qd[0] * (qdd[0] + dq[0]) + qd[1] * r.x() - std::cos(3 * t);
      EXPECT_NEAR(ev.A(0, j), direct2 - direct, 1e-6 * (1 + std::abs(ev.A(0, j)))) << "trial " << trial << " j " << j;
    }
  }
}

TEST(AccelerationConstraint, SolvedRowHoldsAndLagrangeAgreesWithProjection) {
  const auto pp = arm(kHeightAcceleration, 1e-3);
  const auto pl = arm(kHeightAcceleration, 1e-3, "lagrange");
  auto rp = pp->make_reference_dynamics();
  auto rl = pl->make_reference_dynamics();
  std::mt19937 rng(3);
  for (int k = 0; k < 5; ++k) {
    Eigen::VectorXd x = rp->make_state(test::random_vector(rng, 2, 1.0), test::random_vector(rng, 2, 1.0));
    Eigen::VectorXd dp(x.size()), dl(x.size());
    rp->derivative(0.1 * k, x, dp);
    rl->derivative(0.1 * k, x, dl);
    EXPECT_TRUE(test::near(dp, dl, 1e-11, 1e-11));
    // The recorded residual B q̈ + s is the row itself after the solve.
    EXPECT_LT(std::abs(rp->constraints().phi[0]), 1e-12);
    const double s = rp->constraints().gamma[0];
    EXPECT_NEAR(rp->constraints().A.row(0).dot(rp->qdd()), -s, 1e-12 * (1 + std::abs(s)));
    // The reaction acts along Bᵀ: Q_c = M q̈ − F = −Bᵀλ.
    EXPECT_TRUE(test::near(rp->constraint_force(), -rp->constraints().A.transpose() * rp->lambda(), 1e-10, 1e-10));
  }
}

// (a) Φ(q, t) = 0 imposed at the position level (Baumgarte) and, differentiated twice, at the
// acceleration level: the same motion. Reference: the position-level plan with h = 1e-4 (its
// RK4 error is ~(1e-4/h)⁴ below the errors measured here). The acceleration-level plans at
// h = 0.02, 0.01, 0.005 converge to it with order 4 (error ratio 16 per halving, ±25 %: the
// ratio of the leading terms at these steps), and the position-level residual Φ, which the
// acceleration-level plan does not stabilize, stays at the size of its integration error.
TEST(AccelerationConstraint, TwiceDifferentiatedPositionConstraintGivesThePositionLevelMotion) {
  const auto ref_problem = arm(kHeightPosition, 1e-4);
  const Plan ref = plan_of(*ref_problem);
  const Eigen::VectorXd q_ref = final_q(ref);
  std::vector<double> err;
  for (double h : {0.02, 0.01, 0.005}) {
    const auto p = arm(kHeightAcceleration, h);
    const Plan plan = plan_of(*p);
    ASSERT_NEAR(plan.t.back(), 2.0, 1e-12);
    err.push_back((final_q(plan) - q_ref).cwiseAbs().maxCoeff());
    EXPECT_LT(plan.summary.max_constraint_residual, 1e-12);  // |B q̈ + s| at the samples
    // Position residual of the acceleration-level plan, from the recorded q, at every sample.
    ConstraintSet pos;
    pos.add(expression_constraint(p->model, "height", "y(E) - (y0 + h*(1 - cos(w*t))/2)", false, p->parameters));
    Data data(p->model);
    ConstraintEval ev(p->model, pos);
    double worst = 0;
    for (size_t k = 0; k < plan.size(); ++k) {
      evaluate_constraints(p->model, data, pos, ev, plan.t[k], plan.x[k].head(2), plan.x[k].segment(2, 2));
      worst = std::max(worst, std::abs(ev.phi[0]));
      EXPECT_LT(std::abs(plan.phi[k][0]), 1e-12);  // the acceleration row itself, after each solve
    }
    std::printf("[ order a ] h = %.4f: |q(2) - q_ref(2)| = %.3e, max |Phi| = %.3e\n", h, err.back(), worst);
    EXPECT_LT(worst, 10 * err.back() + 1e-12);
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ order a ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  EXPECT_GT(r1, 12);
  EXPECT_LT(r1, 20);
  EXPECT_GT(r2, 12);
  EXPECT_LT(r2, 20);
  EXPECT_LT(err[2], 1e-7);
  // At h = 1e-4 both routes give the same motion to rounding-level integration error.
  const auto fine = arm(kHeightAcceleration, 1e-4);
  const Plan fine_plan = plan_of(*fine);
  const double diff = (final_q(fine_plan) - q_ref).cwiseAbs().maxCoeff();
  std::printf("[ order a ] h = 1e-4: |q_acc - q_pos| = %.3e\n", diff);
  EXPECT_LT(diff, 1e-10);
}

// ---------------------------------------------------------------------------------------------
// (b) A particle P of mass m in a horizontal plane, in polar coordinates (θ, r): a revolute
// joint th about z carrying a massless radial slider r. Its tangential acceleration is
// prescribed, v·a/|v| = a_t(t) = A sin(ωt). The reaction acts along B = ∂f/∂q̈ ∝ vᵀC, i.e.
// along the path: no normal force, so P moves on the straight line of its initial velocity
// with s̈ = a_t: s(t) = v0 t + A (t/ω − sin(ωt)/ω²), and Q_c = Cᵀ (m a_t u).
const char* kParticle = R"(
name: polar_particle
parameters:
  m: 1.7
  A: 0.8
  w: 3.0
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: arm, joint: th, parent: base, type: revolute, axis: [0, 0, 1], mass: 0, inertia: [0, 0, 0]}
    - {name: bead, joint: r, parent: arm, type: prismatic, axis: [1, 0, 0], mass: m, inertia: [0, 0, 0]}
  points:
    P: {link: bead, position: [0, 0, 0]}
constraints:
  - name: tangential
    order: acceleration
    expression: (vx(P)*ax(P) + vy(P)*ay(P))/sqrt(vx(P)^2 + vy(P)^2) - A*sin(w*t)
partition: {independent: [th]}
initial:
  q: {th: 0, r: 1}
  qd: {th: 0.8, r: 0.3}          # v(P) = (0.3, 0.8) m/s
integrator: {method: rk4, step: @STEP@, t0: 0, t1: 3}
)";

struct ParticleExact {
  double m = 1.7, A = 0.8, w = 3.0;
  Eigen::Vector2d p0{1.0, 0.0}, v0{0.3, 0.8};
  Eigen::Vector2d u() const { return v0.normalized(); }
  double s(double t) const { return v0.norm() * t + A * (t / w - std::sin(w * t) / (w * w)); }
  Eigen::Vector2d position(double t) const { return p0 + u() * s(t); }
  Eigen::Vector2d q(double t) const {
    const Eigen::Vector2d p = position(t);
    return {std::atan2(p.y(), p.x()), p.norm()};
  }
};

TEST(AccelerationConstraint, ParticleWithPrescribedTangentialAccelerationMovesOnAStraightLine) {
  const ParticleExact ex;
  std::vector<double> err;
  for (double h : {0.04, 0.02, 0.01}) {
    const auto p = io::parse_problem(replace_all(kParticle, "@STEP@", num(h)), "particle.yaml");
    const Plan plan = plan_of(*p);
    double worst = 0, worst_qc = 0, worst_line = 0;
    for (size_t k = 0; k < plan.size(); ++k) {
      const double t = plan.t[k];
      const Eigen::Vector2d q = plan.x[k].head(2);
      worst = std::max(worst, (q - ex.q(t)).cwiseAbs().maxCoeff());
      // Distance from the initial line (the closed form's path), from the recorded state.
      const Eigen::Vector2d pos(q[1] * std::cos(q[0]), q[1] * std::sin(q[0]));
      const Eigen::Vector2d d = pos - ex.p0;
      worst_line = std::max(worst_line, std::abs(d.x() * ex.u().y() - d.y() * ex.u().x()));
      // Reaction: Q_c = Cᵀ (m a_t u), C = ∂P/∂(θ, r) at the recorded state.
      Eigen::Matrix2d C;
      C << -q[1] * std::sin(q[0]), std::cos(q[0]), q[1] * std::cos(q[0]), std::sin(q[0]);
      const Eigen::Vector2d qc = C.transpose() * (ex.m * ex.A * std::sin(ex.w * t) * ex.u());
      worst_qc = std::max(worst_qc, (plan.Qc[k] - qc).cwiseAbs().maxCoeff());
    }
    err.push_back(worst);
    std::printf("[ order b ] h = %.3f: max |q - q_exact| = %.3e, max distance from the line = %.3e, "
                "max |Q_c - C^T m a_t u| = %.3e\n", h, worst, worst_line, worst_qc);
    EXPECT_LT(worst_line, 2 * worst + 1e-13);
    EXPECT_LT(worst_qc, 1e-6);
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ order b ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  EXPECT_GT(r1, 12);
  EXPECT_LT(r1, 20);
  EXPECT_GT(r2, 12);
  EXPECT_LT(r2, 20);
  EXPECT_LT(err[2], 1e-7);
}

// ---------------------------------------------------------------------------------------------
// A position row and an acceleration row in one problem: the planar 2R arm's tip E stays on a
// circle (holonomic, Baumgarte) and its tangential acceleration along the circle is prescribed,
// t̂·a_E = A sin ωt (acceleration level). n − m = 0: the motion is fully prescribed. Closed form:
// E's angle about C is φ(t) = φ0 + s(t)/R with s(t) = v0 t + A (t/ω − sin(ωt)/ω²), v0 the
// initial speed left by the Newton projection (consistency: project, which ignores the
// acceleration row). Checked: E against the closed form with RK4's order 4.
const char* kCircle = R"(
name: circle_accel
parameters:
  L1: 0.5
  L2: 0.4
  m1: 2.0
  m2: 1.5
  cx: 0.6
  cy: 0.2
  R: 0.15
  A: 0.5
  w: 3.0
  ex0: cx + R
  ey0: cy
  q20: acos((ex0^2 + ey0^2 - L1^2 - L2^2)/(2*L1*L2))
  q10: atan2(ey0, ex0) - atan2(L2*sin(q20), L1 + L2*cos(q20))
model:
  gravity: [0, -9.81, 0]
  links:
    - {name: upper, joint: q1, parent: base, type: revolute, axis: [0, 0, 1],
       mass: m1, com: [L1/2, 0, 0], inertia: [0.001, m1*L1^2/12, m1*L1^2/12]}
    - {name: fore, joint: q2, parent: upper, type: revolute, axis: [0, 0, 1], origin: {xyz: [L1, 0, 0]},
       mass: m2, com: [L2/2, 0, 0], inertia: [0.001, m2*L2^2/12, m2*L2^2/12]}
  points:
    E: {link: fore, position: [L2, 0, 0]}
constraints:
  - name: circle
    expression: (x(E) - cx)^2 + (y(E) - cy)^2 - R^2
  - name: tangential_acceleration
    order: acceleration
    expression: (-(y(E) - cy)*ax(E) + (x(E) - cx)*ay(E))/R - A*sin(w*t)
partition:
  independent: []
baumgarte: {alpha: 10, beta: 10} # |λh| inside RK4's stability region at h = 0.02
initial:
  q: {q1: q10, q2: q20}
  qd: {q1: 1.5, q2: 0.2}         # projected onto the circle's tangent
  consistency: project
integrator: {method: rk4, step: @STEP@, t0: 0, t1: 3}
)";

TEST(AccelerationConstraint, MixedWithAHolonomicRowFollowsTheClosedForm) {
  std::vector<double> err;
  for (double h : {0.02, 0.01, 0.005}) {
    const auto p = io::parse_problem(replace_all(kCircle, "@STEP@", num(h)), "circle.yaml");
    EXPECT_EQ(p->constraints.row_order(0), 0);
    EXPECT_EQ(p->constraints.row_order(1), 2);
    const Plan plan = plan_of(*p);
    const double cx = 0.6, cy = 0.2, R = 0.15, A = 0.5, w = 3.0;
    // Initial speed along the circle from the projected state (E's velocity from the record).
    const Eigen::Vector2d e0 = plan.point_positions[0].head(2);
    ConstraintSet probe;
    probe.add(expression_constraint(p->model, "v", "(-(y(E) - cy)*vx(E) + (x(E) - cx)*vy(E))/R", true, p->parameters));
    Data data(p->model);
    ConstraintEval ev(p->model, probe);
    evaluate_constraints(p->model, data, probe, ev, 0.0, p->q0, p->qd0);
    const double v0 = ev.phi[0];
    const double phi0 = std::atan2(e0.y() - cy, e0.x() - cx);
    double worst = 0;
    for (size_t k = 0; k < plan.size(); ++k) {
      const double t = plan.t[k];
      const double phi = phi0 + (v0 * t + A * (t / w - std::sin(w * t) / (w * w))) / R;
      const Eigen::Vector2d exact(cx + R * std::cos(phi), cy + R * std::sin(phi));
      worst = std::max(worst, (plan.point_positions[k].head(2) - exact).cwiseAbs().maxCoeff());
      EXPECT_LT(std::abs(plan.phi[k][1]), 1e-12);  // the acceleration row, after each solve
    }
    err.push_back(worst);
    std::printf("[ mixed ] h = %.3f: v0 = %.6f m/s, max |E - E_exact| = %.3e, max |Phi| = %.2e\n", h, v0, worst,
                plan.summary.max_constraint_residual);
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ mixed ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  EXPECT_GT(r1, 12);
  EXPECT_LT(r1, 20);
  EXPECT_GT(r2, 12);
  EXPECT_LT(r2, 20);
  EXPECT_LT(err[2], 2e-7);
}

// ---------------------------------------------------------------------------------------------
// Bad inputs: each rejected by build_problem with one located message naming the key.
std::string bad_arm(const std::string& constraint) {
  std::string y = replace_all(kArm, "@CONSTRAINT@", constraint);
  y = replace_all(y, "@STEP@", "1e-3");
  return replace_all(y, "@SOLVER@", "");
}

TEST(AccelerationConstraint, BadInputsAreRejectedWithTheirKey) {
  const std::string key = "constraints.c.order";
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleraton\n    expression: ay(E)"), "a.yaml"); },
      {"a.yaml:", key, "acceleraton", "did you mean 'acceleration'"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: jerk\n    expression: ay(E)"), "a.yaml"); },
      {"a.yaml:", "constraints.c", "order: jerk", "involves no jerk"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleration\n    expression: vy(E) - 1"), "a.yaml"); },
      {"a.yaml:", "constraints.c", "involves no acceleration"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleration\n    expression: ay(E)^2 - 1"), "a.yaml"); },
      {"a.yaml:", "constraints.c", "linear in the accelerations", "ay(E)"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleration\n    expression: ax(E)*ay(E)"), "a.yaml"); },
      {"linear in the accelerations"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    expression: ay(E) - 1"), "a.yaml"); },
      {"a.yaml:", "constraints.c", "order: acceleration"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: velocity\n    expression: qdd(q1)"), "a.yaml"); },
      {"a.yaml:", "order: acceleration"});
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleration\n    expression: jx(E)"), "a.yaml"); },
      {"a.yaml:", "jx(E)", "only in jerk constraints"});
  // B = 0 at t0 (the constraint does not act on the accelerations there): a singular row.
  test::expect_error_mentioning(
      [&] { io::parse_problem(bad_arm("  - name: c\n    order: acceleration\n    expression: t*ay(E) - 1"), "a.yaml"); },
      {"a.yaml:", "constraints.c", "does not act on the accelerations"});
}

}  // namespace
