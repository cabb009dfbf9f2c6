// Programmed constraints of order p = 3 (jerk), jerk.hpp:
//  - the dual-number (forward-mode AD) recursive Newton–Euler: τ equals the double RNEA, τ̇
//    equals central differences of τ along the motion, on random trees with prismatic joints;
//  - point motion (r, v, a, jerk at q⃛ = 0, C, Ċ) against the double kinematics and differences;
//  - the jerk constraint's s, B, Ḃ against differences;
//  - (c) a closed form: a particle in polar coordinates with prescribed tangential jerk moves
//    on a straight line with s⃛ = J sin ωt; RK4's order 4 measured; reactions Q_c = Cᵀ m s̈ u;
//  - consistent initial accelerations; bad expressions rejected by name.
#include "refdyn/io/scenario.hpp"
#include "refdyn/reference/jerk.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace refdyn;

namespace {

struct Curve {  // q(τ) = q + q̇τ + q̈τ²/2 (q⃛ = 0), q̇(τ), q̈(τ)
  Eigen::VectorXd q, qd, qdd;
  Eigen::VectorXd at(double s) const { return q + qd * s + 0.5 * qdd * s * s; }
  Eigen::VectorXd vel(double s) const { return qd + qdd * s; }
};

TEST(JerkAD, InverseDynamicsRateMatchesRneaAndFiniteDifferences) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 12; ++trial) {
    test::RandomChainOptions o;
    o.dof = 2 + trial % 5;
    o.tree = trial % 3 == 2;
    o.prismatic_fraction = 0.4;
    const Model m = build_model(test::random_chain(rng, o));
    Data data(m);
    const int n = m.nv;
    const Curve c{test::random_vector(rng, n, 1.0), test::random_vector(rng, n, 1.5), test::random_vector(rng, n, 2.0)};
    Eigen::VectorXd tau, taud;
    inverse_dynamics_rate(m, c.q, c.qd, c.qdd, tau, taud);
    const Eigen::VectorXd ref = inverse_dynamics(m, data, c.q, c.qd, c.qdd);
    EXPECT_TRUE(test::near(tau, ref, 1e-12, 1e-12)) << "trial " << trial;
    const double e = 1e-6;
    const Eigen::VectorXd tp = inverse_dynamics(m, data, c.at(e), c.vel(e), c.qdd);
    const Eigen::VectorXd tm = inverse_dynamics(m, data, c.at(-e), c.vel(-e), c.qdd);
    EXPECT_TRUE(test::near(taud, (tp - tm) / (2 * e), 1e-7, 1e-7)) << "trial " << trial;
  }
}

TEST(JerkAD, PointMotionMatchesKinematicsAndFiniteDifferences) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    test::RandomChainOptions o;
    o.dof = 2 + trial % 5;
    o.tree = trial % 4 == 3;
    const Model m = build_model(test::random_chain(rng, o));
    Data data(m);
    const int n = m.nv, tip = m.point_index("tip");
    const Curve c{test::random_vector(rng, n, 1.0), test::random_vector(rng, n, 1.5), test::random_vector(rng, n, 2.0)};
    PointMotion pm;
    point_motion(m, c.q, c.qd, c.qdd, tip, pm);
    forward_kinematics(m, data, c.q);
    EXPECT_TRUE(test::near(pm.r, point_position(m, data, tip), 1e-13, 1e-13));
    point_jacobian(m, data, tip);
    const Eigen::MatrixXd C = data.Jp;
    EXPECT_TRUE(test::near(pm.C, C, 1e-12, 1e-12));
    const PointDrift pd = point_drift(m, data, tip, c.qd);
    EXPECT_TRUE(test::near(pm.v, pd.velocity, 1e-12, 1e-12));
    EXPECT_TRUE(test::near(pm.a, C * c.qdd + pd.drift, 1e-11, 1e-11));
    // Jerk at q⃛ = 0 and Ċ by central differences along the curve.
    const double e = 1e-5;
    PointMotion pp, pn;
    point_motion(m, c.at(e), c.vel(e), c.qdd, tip, pp);
    point_motion(m, c.at(-e), c.vel(-e), c.qdd, tip, pn);
    EXPECT_TRUE(test::near(pm.j, (pp.a - pn.a) / (2 * e), 1e-7, 1e-7)) << "trial " << trial;
    EXPECT_TRUE(test::near(pm.Cdot, (pp.C - pn.C) / (2 * e), 1e-7, 1e-7)) << "trial " << trial;
  }
}

// ---------------------------------------------------------------------------------------------
// The particle of tests/higher_order_test.cpp (polar coordinates: a revolute joint th and a
// massless radial slider r carrying a point mass m at P, no gravity in the plane).
ModelDescription polar_particle(double mass) {
  ModelDescription d;
  LinkSpec arm;
  arm.name = "arm";
  arm.joint_name = "th";
  arm.type = JointType::Revolute;
  arm.axis = Vec3::UnitZ();
  d.add_link(arm);
  LinkSpec bead;
  bead.name = "bead";
  bead.joint_name = "r";
  bead.parent = 0;
  bead.type = JointType::Prismatic;
  bead.axis = Vec3::UnitX();
  bead.inertia.mass = mass;
  d.add_link(bead);
  d.add_point("P", "bead", Vec3::Zero());
  d.gravity = Vec3(0, 0, -9.81);
  return d;
}

TEST(JerkConstraint, SBAndBdotMatchFiniteDifferences) {
  std::mt19937 rng(9);
  test::RandomChainOptions o;
  o.dof = 3;
  const Model m = build_model(test::random_chain(rng, o));
  const std::string text = "(2 + sin(q(q1)))*jx(tip) + vy(tip)*jz(tip) + t*qddd(q2) + x(tip)*ay(tip) - qdd(q3)^2 - cos(t)";
  const JerkConstraint jc(m, "c", text);
  const int n = m.nv, tip = m.point_index("tip");
  std::vector<PointMotion> pts(m.point_name.size());
  for (int trial = 0; trial < 4; ++trial) {
    const Curve c{test::random_vector(rng, n, 1.0), test::random_vector(rng, n, 1.5), test::random_vector(rng, n, 2.0)};
    const Eigen::VectorXd qddd = test::random_vector(rng, n, 2.0);
    const double t = 0.3 + trial;
    auto direct = [&](double tt, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                      const Eigen::VectorXd& jerk) {  // f evaluated with the full point jerk j + C q⃛
      PointMotion p;
      point_motion(m, q, qd, qdd, tip, p);
      const Vec3 jj = p.j + p.C * jerk;
      return (2 + std::sin(q[0])) * jj.x() + p.v.y() * jj.z() + tt * jerk[1] + p.r.x() * p.a.y() - qdd[2] * qdd[2] -
             std::cos(tt);
    };
    point_motion(m, c.q, c.qd, c.qdd, tip, pts[tip]);
    double s;
    Eigen::RowVectorXd B(n), Bdot(n);
    jc.evaluate(t, c.q, c.qd, c.qdd, pts, s, B, Bdot);
    const double f = direct(t, c.q, c.qd, c.qdd, qddd);
    EXPECT_NEAR(s + B.dot(qddd), f, 1e-11 * (1 + std::abs(f)));
    // Ḃ by differences along the motion (t, q, q̇, q̈ all moving; q⃛ held).
    const double e = 1e-5;
    auto B_at = [&](double sgn) {
      const double tt = t + sgn * e;
      const Eigen::VectorXd q = c.q + sgn * e * c.qd + 0.5 * e * e * c.qdd, qd = c.qd + sgn * e * c.qdd;
      std::vector<PointMotion> p2(m.point_name.size());
      point_motion(m, q, qd, c.qdd, tip, p2[tip]);
      double s2;
      Eigen::RowVectorXd B2(n), Bd2(n);
      jc.evaluate(tt, q, qd, c.qdd, p2, s2, B2, Bd2);
      return Eigen::RowVectorXd(B2);
    };
    EXPECT_TRUE(test::near(Bdot, (B_at(1) - B_at(-1)) / (2 * e), 1e-7, 1e-7)) << "trial " << trial;
  }
  test::expect_error_mentioning([&] { JerkConstraint(m, "c", "ax(tip) - 1"); }, {"'c'", "involves no jerk"});
  test::expect_error_mentioning([&] { JerkConstraint(m, "c", "jx(tip)^2"); }, {"'c'", "linear in the jerks"});
  test::expect_error_mentioning([&] { JerkConstraint(m, "c", "ax(tip)*jx(tip)"); },
                                {"'c'", "do not depend on accelerations", "ax(tip)"});
}

// (c) Tangential jerk prescribed, u·j_P = J sin ωt with u = v/|v|: the coefficient of the jerk,
// vᵀC/|v|, is B; the reaction along Bᵀ is tangential, so with a tangential initial
// acceleration a0 (given through the hint) the particle moves on the line of its initial
// velocity with s⃛ = J sin ωt:
//   s(t) = v0 t + a0 t²/2 + J (t²/(2ω) + (cos ωt − 1)/ω³),  s̈(t) = a0 + J (1 − cos ωt)/ω,
// and Q_c = M q̈ − F = Cᵀ m s̈ u.
TEST(JerkDynamics, ParticleWithPrescribedTangentialJerkMovesOnAStraightLine) {
  const double mass = 1.7, J = 0.9, w = 2.0, a0 = 0.4;
  const Model m = build_model(polar_particle(mass));
  const Eigen::Vector2d p0(1.0, 0.0), v0(0.3, 0.8), u = v0.normalized();
  auto s = [&](double t) {
    return v0.norm() * t + a0 * t * t / 2 + J * (t * t / (2 * w) + (std::cos(w * t) - 1) / (w * w * w));
  };
  auto sdd = [&](double t) { return a0 + J * (1 - std::cos(w * t)) / w; };
  auto q_exact = [&](double t) {
    const Eigen::Vector2d p = p0 + u * s(t);
    return Eigen::Vector2d(std::atan2(p.y(), p.x()), p.norm());
  };
  std::map<std::string, double> par{{"J", J}, {"w", w}};
  auto jc = std::make_shared<JerkConstraint>(m, "tangential_jerk",
                                             "(vx(P)*jx(P) + vy(P)*jy(P))/sqrt(vx(P)^2 + vy(P)^2) - J*sin(w*t)", par);
  // Steps with κh ≤ 1 (κ = 50 /s): the gain's own discretization error then stays below RK4's
  // leading term (at h = 0.04, κh = 2, the ratio is 24, not 16).
  std::vector<double> err, err_qc;
  for (double h : {0.02, 0.01, 0.005}) {
    JerkDynamics jd(m, {jc}, JerkDynamicsOptions{50.0});
    const Eigen::Vector2d q0(0.0, 1.0), qd0(0.8, 0.3);  // v(P) = (0.3, 0.8) at θ = 0, r = 1
    // Hint: the initial acceleration a0 u in joint space (at θ = 0: ẍ = r̈ − r θ̇², ÿ = r θ̈ + 2ṙ θ̇).
    const Eigen::Vector2d acc = a0 * u;
    Eigen::VectorXd hint(2);
    hint << (acc.y() - 2 * qd0[1] * qd0[0]) / q0[1], acc.x() + q0[1] * qd0[0] * qd0[0];
    const Eigen::VectorXd x0 = jd.initial_state(0.0, q0, qd0, &hint);
    EXPECT_TRUE(test::near(x0.tail(2), hint, 1e-12, 1e-12));  // one row, the hint is consistent: kept
    IntegratorOptions io;
    io.step = h;
    io.t1 = 3.0;
    const Plan plan = plan_jerk_motion(jd, x0, {io, 0.0, RecordOptions{{m.point_index("P")}}});
    ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
    double worst = 0, worst_qc = 0, worst_row = 0;
    for (size_t k = 0; k < plan.size(); ++k) {
      const double t = plan.t[k];
      const Eigen::Vector2d q = plan.x[k].head(2);
      worst = std::max(worst, (q - q_exact(t)).cwiseAbs().maxCoeff());
      Eigen::Matrix2d C;
      C << -q[1] * std::sin(q[0]), std::cos(q[0]), q[1] * std::cos(q[0]), std::sin(q[0]);
      worst_qc = std::max(worst_qc, (plan.Qc[k] - C.transpose() * (mass * sdd(t) * u)).cwiseAbs().maxCoeff());
      worst_row = std::max(worst_row, std::abs(plan.phi[k][0]));
    }
    err.push_back(worst);
    err_qc.push_back(worst_qc);
    std::printf("[ order c ] h = %.3f: max |q - q_exact| = %.3e, max |Q_c - C^T m s'' u| = %.3e, max |B qddd + s| = "
                "%.1e, max dynamics residual = %.1e\n", h, worst, worst_qc, worst_row,
                plan.summary.max_constraint_residual);
    EXPECT_LT(worst_row, 1e-12);
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ order c ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  EXPECT_GT(r1, 12);
  EXPECT_LT(r1, 20);
  EXPECT_GT(r2, 12);
  EXPECT_LT(r2, 20);
  EXPECT_LT(err[2], 1e-8);
  // The reaction (carried by the state q̈) converges with the same order.
  const double c1 = err_qc[0] / err_qc[1], c2 = err_qc[1] / err_qc[2];
  std::printf("[ order c ] Q_c error ratios %.2f, %.2f\n", c1, c2);
  EXPECT_GT(c1, 12);
  EXPECT_GT(c2, 12);
  EXPECT_LT(err_qc[2], 1e-6);
}

// Without a hint the initial acceleration is the free one (λ0 = 0), with one the constrained
// components are the hint's; either way Nᵀ(M q̈0 − F) = 0, i.e. M q̈0 − F lies along Bᵀ.
TEST(JerkDynamics, InitialAccelerationIsConsistentWithTheDynamics) {
  std::mt19937 rng(2);
  test::RandomChainOptions o;
  o.dof = 4;
  const Model m = build_model(test::random_chain(rng, o));
  auto c1 = std::make_shared<JerkConstraint>(m, "a", "jx(tip) + q(q1)*qddd(q2) - 0.3");
  auto c2 = std::make_shared<JerkConstraint>(m, "b", "jz(tip) - vx(tip)*sin(t)");
  JerkDynamics jd(m, {c1, c2});
  const Eigen::VectorXd q0 = test::random_vector(rng, 4, 1.0), qd0 = test::random_vector(rng, 4, 1.0),
                        hint = test::random_vector(rng, 4, 2.0);
  Data data(m);
  for (const Eigen::VectorXd* h : {static_cast<const Eigen::VectorXd*>(nullptr), &hint}) {
    const Eigen::VectorXd x0 = jd.initial_state(0.2, q0, qd0, h);
    Eigen::VectorXd dx(x0.size());
    jd.derivative(0.2, x0, dx);
    const Eigen::VectorXd R = inverse_dynamics(m, data, q0, qd0, x0.tail(4));  // M q̈0 − F
    EXPECT_TRUE(test::near(R, -jd.B().transpose() * jd.lambda(), 1e-10, 1e-10));  // Q_c = −Bᵀλ
    EXPECT_LT(jd.dynamics_residual(), 1e-10);
    if (h) EXPECT_TRUE(test::near(jd.B() * x0.tail(4), jd.B() * hint, 1e-10, 1e-10));
    else EXPECT_TRUE(test::near(jd.lambda(), Eigen::VectorXd::Zero(2), 0, 1e-10));
    EXPECT_LT(jd.row_residual().cwiseAbs().maxCoeff(), 1e-10);
  }
}

// ---------------------------------------------------------------------------------------------
// The same particle as a scenario: `order: jerk`, `initial.qdd`, `baumgarte.kappa`, through
// build_problem and plan_problem (what `refdyn plan` runs) — the same plan as the library route.
const char* kParticleJerk = R"(
name: particle_jerk
parameters: {m: 1.7, J: 0.9, w: 2.0}
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: arm, joint: th, parent: base, type: revolute, axis: [0, 0, 1], mass: 0, inertia: [0, 0, 0]}
    - {name: bead, joint: r, parent: arm, type: prismatic, axis: [1, 0, 0], mass: m, inertia: [0, 0, 0]}
  points:
    P: {link: bead, position: [0, 0, 0]}
constraints:
  - name: tangential_jerk
    order: jerk
    expression: (vx(P)*jx(P) + vy(P)*jy(P))/sqrt(vx(P)^2 + vy(P)^2) - J*sin(w*t)
baumgarte: {kappa: 50}
initial:
  q: {th: 0, r: 1}
  qd: {th: 0.8, r: 0.3}
  qdd: {th: -0.16, r: 0.76}      # (a0 u_y - 2 r' th')/r, a0 u_x + r th'^2 with a0 = 0.4, u = (0.3, 0.8)/0.854
integrator: {method: rk4, step: 0.01, t0: 0, t1: 3}
)";

TEST(JerkScenario, OrderJerkPlansLikeTheLibraryRoute) {
  const auto p = io::parse_problem(kParticleJerk, "particle_jerk.yaml");
  ASSERT_TRUE(p->is_jerk_problem());
  EXPECT_EQ(p->constraints.row_order(0), 3);
  auto rd = p->make_reference_dynamics();
  const Plan a = plan_problem(*p, *rd);
  ASSERT_TRUE(a.summary.ok()) << a.summary.message;
  JerkDynamics jd(p->model, p->jerk_constraints, JerkDynamicsOptions{50.0});
  const Eigen::VectorXd x0 = jd.initial_state(0.0, p->q0, p->qd0, &p->qdd0);
  IntegratorOptions io;
  io.step = 0.01;
  io.t1 = 3.0;
  const Plan b = plan_jerk_motion(jd, x0, {io, 0.0, RecordOptions{{0}}});
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a.x[k], b.x[k]) << "sample " << k;
  EXPECT_EQ(a.state_names, (std::vector<std::string>{"acc_th", "acc_r"}));
  EXPECT_LT(a.summary.max_constraint_residual, 1e-5);
}

std::string jerk_variant(const std::string& from, const std::string& to) {
  std::string y = kParticleJerk;
  const size_t pos = y.find(from);
  if (pos == std::string::npos) throw std::runtime_error("no '" + from + "' in the scenario");
  return y.replace(pos, from.size(), to);
}

TEST(JerkScenario, BadInputsAreRejectedWithTheirKey) {
  auto bad = [](const std::string& yaml, const std::vector<std::string>& needles) {
    test::expect_error_mentioning([&] { io::parse_problem(yaml, "j.yaml"); }, needles);
  };
  // Rows of lower order and force elements with states are part of jerk problems now (mixed
  // orders, tests/mixed_order_test.cpp); what stays unsupported is named with its key.
  EXPECT_NO_THROW(io::parse_problem(jerk_variant("constraints:\n", "constraints:\n  - {name: ring, expression: q(r) - 1 - 0.3*t}\n"), "ok.yaml"));
  bad(jerk_variant("integrator: {method: rk4,", "integrator: {method: bdf,"), {"j.yaml:", "integrator.method", "jerk"});
  bad(jerk_variant("baumgarte: {kappa: 50}", "baumgarte: {kappa: 50}\nstabilization: projection"),
      {"j.yaml:", "stabilization", "jerk"});
  bad(jerk_variant("    order: jerk\n", "    order: jerk\n    differentiate: true\n"),
      {"constraints.tangential_jerk", "jerk", "order 4"});
  bad(jerk_variant("  qdd: {th: -0.16, r: 0.76}", "  qdd: {consistent_with: tangential}"),
      {"initial.qdd.consistent_with", "not a jerk constraint", "tangential_jerk"});
  bad(jerk_variant("  qdd: {th: -0.16, r: 0.76}", "  qdd: {consistent_with: tangential_jerk}"),
      {"initial.qdd.consistent_with", "differentiate: true"});
  bad(jerk_variant("  qdd: {th: -0.16, r: 0.76}", "  qdd: {consistent_with: tangential_jerk, th: 1}"),
      {"initial.qdd", "not both"});
  bad(jerk_variant("baumgarte: {kappa: 50}", "baumgarte: {kappa: -1}"), {"j.yaml:", "baumgarte.kappa", ">= 0"});
  bad(jerk_variant("order: jerk", "order: jerck"), {"constraints.tangential_jerk.order", "did you mean 'jerk'"});
  bad(jerk_variant("order: jerk", "order: acceleration"), {"constraints.tangential_jerk", "order: jerk"});
  bad(jerk_variant("    expression: (vx(P)*jx(P) + vy(P)*jy(P))", "    expression: (vx(P)*ax(P) + vy(P)*ay(P))"),
      {"constraints.tangential_jerk", "involves no jerk"});
  bad(jerk_variant("    expression: (vx(P)*jx(P)", "    expression: (ax(P)*jx(P)"),
      {"constraints.tangential_jerk", "do not depend on accelerations"});
  bad(jerk_variant("    order: jerk\n", "    origin: material\n    order: jerk\n"),
      {"constraints.tangential_jerk.origin", "programmed"});
  // Keys of jerk problems elsewhere.
  const std::string acc = jerk_variant("    order: jerk\n    expression: (vx(P)*jx(P) + vy(P)*jy(P))",
                                       "    order: acceleration\n    expression: (vx(P)*ax(P) + vy(P)*ay(P))");
  const size_t qdd_line = acc.find("  qdd:");
  const std::string acc_no_qdd = acc.substr(0, qdd_line) + acc.substr(acc.find('\n', qdd_line) + 1);
  auto without_baumgarte = [](const std::string& y) {
    const size_t b = y.find("baumgarte:");
    return y.substr(0, b) + y.substr(y.find('\n', b) + 1);
  };
  EXPECT_NO_THROW(io::parse_problem(without_baumgarte(acc_no_qdd), "ok.yaml"));
  bad(acc_no_qdd, {"baumgarte.kappa", "jerk"});
  bad(without_baumgarte(acc), {"initial.qdd", "jerk"});
}

// (a) for p = 3: a position constraint differentiated three times and imposed at the jerk level
// gives the position-level plan's motion. A 2R arm in a vertical plane (gravity, so λ ≠ 0 and
// Ṅ ≠ 0) with damping, a spring, a flexible drive and a prescribed effort (their rates enter
// Ṙ), E's height y0 + h(1 − cos ωt)/2, consistent q0, q̇0 and (through initial.qdd) the
// position-level plan's q̈0. Reference: the position-level plan at h = 1e-4.
const char* kArmJerk = R"(
name: arm
parameters:
  L1: 0.5
  L2: 0.4
  m1: 2.0
  m2: 1.5
  q10: 0.3
  q20: 1.1
  w: 2.5
  h: 0.12
  y0: L1*sin(q10) + L2*sin(q10 + q20)
  qd10: 0.6
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
forces:                        # every kind that provides its rate (add_rate)
  - {type: damping, joint: q1, coefficient: 0.3}
  - {type: spring, joint: q2, stiffness: 2, rest: 1.0}
  - {type: flexible_drive, joint: q1, stiffness: 50, damping: 5,
     profile: {raised_cosine: {base: q10, amplitude: 0.3, period: 2}}}
  - {type: effort, joint: q2, value: 0.2*sin(3*t)}
constraints:
@CONSTRAINT@
initial:
  q: {q1: q10, q2: q20}
  qd: {q1: qd10, q2: qd20}
@QDD@
integrator: {method: rk4, step: @STEP@, t0: 0, t1: 2}
)";

std::string arm_jerk(const std::string& constraint, double step, const std::string& qdd) {
  std::string y = kArmJerk;
  auto put = [&](const std::string& k, const std::string& v) { y.replace(y.find(k), k.size(), v); };
  put("@CONSTRAINT@", constraint);
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", step);
  put("@STEP@", b);
  put("@QDD@", qdd);
  return y;
}

TEST(JerkScenario, ThriceDifferentiatedPositionConstraintGivesThePositionLevelMotion) {
  const auto ref_p = io::parse_problem(
      arm_jerk("  - {name: height, expression: y(E) - (y0 + h*(1 - cos(w*t))/2)}", 1e-4, ""), "arm.yaml");
  auto ref_rd = ref_p->make_reference_dynamics();
  const Plan ref = plan_problem(*ref_p, *ref_rd);
  ASSERT_TRUE(ref.summary.ok()) << ref.summary.message;
  char qdd[160];
  std::snprintf(qdd, sizeof qdd, "  qdd: {q1: %.17g, q2: %.17g}", ref.qdd[0][0], ref.qdd[0][1]);
  std::vector<double> err;
  // Steps with κh ≤ 0.25 (κ = 50 /s): at h = 0.01 the ratio to h = 0.005 is still 29 (pre-
  // asymptotic: the gain's transient and the drive's 10 rad/s mode); from h = 0.005 on it tends
  // to 16 (20.5, then 14.6).
  for (double h : {0.005, 0.0025, 0.00125, 1e-4}) {
    const auto p = io::parse_problem(
        arm_jerk("  - {name: height, order: jerk, expression: jy(E) + h*w^3*sin(w*t)/2}", h, qdd), "arm.yaml");
    auto rd = p->make_reference_dynamics();
    const Plan plan = plan_problem(*p, *rd);
    ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
    ASSERT_NEAR(plan.t.back(), 2.0, 1e-12);
    EXPECT_TRUE(test::near(plan.qdd[0], ref.qdd[0], 1e-12, 1e-12));  // the hint is consistent: kept
    // Max over the samples at t = 0.01 k (every sample of the coarsest plan).
    const size_t every = static_cast<size_t>(std::lround(0.01 / h)), ref_every = 100;  // h = 1e-4: every = 100
    double e = 0;
    for (size_t k = 0; k * every < plan.size(); ++k)
      e = std::max(e, (plan.x[k * every].head(2) - ref.x[k * ref_every].head(2)).cwiseAbs().maxCoeff());
    err.push_back(e);
    std::printf("[ order a3 ] h = %.4f: max |q - q_ref| at t = 0.01 k = %.3e, max dynamics residual %.2e\n", h, err.back(),
                plan.summary.max_constraint_residual);
  }
  // The position residual the jerk-level plan does not stabilize (y − y_a, and its rates) grows
  // from integration errors like t²: the motion is sensitive (λ ~ 40 N, q̈ up to 14 rad/s²), so
  // the errors are larger than at p = 2 for the same step, with the same order.
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ order a3 ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  for (double r : {r1, r2}) {
    EXPECT_GT(r, 12);
    EXPECT_LT(r, 24);
  }
  EXPECT_LT(std::abs(std::log2(r2) - 4), 0.25);  // the finest pair: order 4 ± 0.25
  EXPECT_LT(err[2], 1e-7);
  EXPECT_LT(err[3], 1e-10);  // h = 1e-4: both routes agree to the reference's own accuracy
}

// The rates of the force elements (ForceElement::add_rate) against central differences of
// their forces along q(τ) = q + q̇τ + q̈τ²/2, t + τ; LuGre (with a state) provides none.
TEST(JerkForces, RatesMatchFiniteDifferences) {
  std::mt19937 rng(4);
  test::RandomChainOptions o;
  o.dof = 3;
  const Model m = build_model(test::random_chain(rng, o));
  ForceSet fs;
  fs.add(joint_damping(m, "q1", 0.7));
  fs.add(joint_spring(m, "q2", 3.0, 0.4));
  fs.add(joint_effort(m, "q3", expression_time_function("0.5*sin(2*t) + t^2", {})));
  fs.add(std::make_shared<FlexibleDrive>(m, "q1", FlexibleDriveParams{40.0, 3.0},
                                         expression_time_function("0.3*cos(1.5*t)", {})));
  const Curve c{test::random_vector(rng, 3, 1.0), test::random_vector(rng, 3, 1.5), test::random_vector(rng, 3, 2.0)};
  const double t = 0.8, e = 1e-6;
  Eigen::VectorXd Qp(3), Qm(3), rate = Eigen::VectorXd::Zero(3);
  double z = 0, zd = 0;
  fs.evaluate(t + e, c.at(e), c.vel(e), &z, Qp, &zd);
  fs.evaluate(t - e, c.at(-e), c.vel(-e), &z, Qm, &zd);
  for (const auto& f : fs.elements()) EXPECT_TRUE(f->add_rate(t, c.q, c.qd, c.qdd, rate)) << f->name();
  EXPECT_TRUE(test::near(rate, (Qp - Qm) / (2 * e), 1e-7, 1e-7));
  // LuGre (a state z, no explicit time): no rate without its state, an exact one with it, against
  // central differences of Q along (q, q̇, z) with z(τ) = z + ż τ + z̈ τ²/2 (z̈ from differences of ż).
  LuGreFriction lugre(m, "q2", LuGreParams{0.1, 0.2, 50.0, 1.0, 0.1, 0.175});
  EXPECT_FALSE(lugre.add_rate(t, c.q, c.qd, c.qdd, rate));
  const double z0 = 0.003;
  Eigen::VectorXd Q0 = Eigen::VectorXd::Zero(3), Qa = Q0, Qb = Q0, lrate = Q0;
  double zd0 = 0, zda = 0, zdb = 0;
  lugre.apply(t, c.q, c.qd, &z0, Q0, &zd0, nullptr);
  EXPECT_TRUE(lugre.add_rate_with_states(t, c.q, c.qd, c.qdd, &z0, &zd0, lrate));
  const double za = z0 + zd0 * e, zb = z0 - zd0 * e;  // first order in z suffices: Q is linear in z, ż
  lugre.apply(t, c.at(e), c.vel(e), &za, Qa, &zda, nullptr);
  lugre.apply(t, c.at(-e), c.vel(-e), &zb, Qb, &zdb, nullptr);
  EXPECT_TRUE(test::near(lrate, (Qa - Qb) / (2 * e), 1e-6, 1e-6)) << lrate.transpose() << " vs "
                                                                   << ((Qa - Qb) / (2 * e)).transpose();
  ForceSet with_state;
  with_state.add(std::make_shared<LuGreFriction>(m, "q2", LuGreParams{}));
  EXPECT_NO_THROW(JerkDynamics(m, std::vector<JerkConstraintPtr>{}, JerkDynamicsOptions{}, &with_state));
}

}  // namespace
