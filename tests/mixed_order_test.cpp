// Mixed orders (docs/higher_order.md, "Mixed orders"): rows of order 0, 1, 2 beside jerk rows,
// rows differentiated by refdyn (differentiate: true), consistent initial accelerations, force
// elements with states, drives recorded, tracking of jerk plans; a closed form.
#include "test_support.hpp"

#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdio>
#include <string>
#include <vector>

namespace refdyn {
namespace {

// A spatial 3R arm (q1 about z, q2 and q3 about y, gravity along −z) whose tip E keeps its height
// (a holonomic row, rheonomic: z(E) = z0 + a sin t) while its wrist follows an acceleration-level
// law (the issue's row) — written once at the acceleration level (the reference problem) and
// once as its time derivative at the jerk level.
const char* kArm = R"(
name: mixed
parameters:
  L1: 0.5
  L2: 0.4
  L3: 0.3
  a: 0.05
  q10: 0.4
  q20: -0.6
  q30: 0.9
  qd20: -0.1
  qd30: 0.2
  c2: -L2*cos(q20) - L3*cos(q20 + q30)
  c3: -L3*cos(q20 + q30)
  z0: -L2*sin(q20) - L3*sin(q20 + q30)
  qd10: 0.3
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: l1, joint: q1, parent: base, type: revolute, axis: [0, 0, 1],
       mass: 2.0, com: [0, 0, 0.1], inertia: [0.02, 0.02, 0.01]}
    - {name: l2, joint: q2, parent: l1, type: revolute, axis: [0, 1, 0], origin: {xyz: [0, 0, 0]},
       mass: 1.5, com: [L2/2, 0, 0], inertia: [0.001, 0.02, 0.02]}
    - {name: l3, joint: q3, parent: l2, type: revolute, axis: [0, 1, 0], origin: {xyz: [L2, 0, 0]},
       mass: 0.8, com: [L3/2, 0, 0], inertia: [0.001, 0.006, 0.006]}
  points:
    E: {link: l3, position: [L3, 0, 0]}
constraints:
  - name: height
    expression: z(E) - z0 - a*sin(t)
  - name: wrist
@WRIST@
forces:
@FORCES@
baumgarte: {kappa: 50}
initial:
  q: {q1: q10, q2: q20, q3: q30}
  qd: {q1: qd10, q2: (a - c3*qd30)/c2, q3: qd30}
@QDD@
integrator: {method: rk4, step: @STEP@, t0: 0, t1: @T1@}
)";

const char* kWristAcceleration = "qdd(q3) + 0.4*cos(q(q2))*az(E) + 0.2*qd(q1)*ay(E) - 1.2*cos(2*t)";
// Its time derivative, by hand (the issue's text).
const char* kWristJerk = "qddd(q3) - 0.4*sin(q(q2))*qd(q2)*az(E) + 0.4*cos(q(q2))*jz(E) + 0.2*qdd(q1)*ay(E) + "
                         "0.2*qd(q1)*jy(E) + 2.4*sin(2*t)";
const char* kSmoothForces =
    "  - {type: damping, joint: q2, coefficient: 0.3}\n"
    "  - {type: spring, joint: q1, stiffness: 2, rest: 0.4}\n"
    "  - {type: effort, joint: q1, value: 0.2*sin(3*t)}\n"
    "  - {type: flexible_drive, joint: q3, stiffness: 50, damping: 5,\n"
    "     profile: {raised_cosine: {base: q30, amplitude: 0.3, period: 2}}}\n";

enum class Wrist { Acceleration, Differentiated, ByHand };

std::string arm(Wrist w, double step, double t1, const std::string& forces = kSmoothForces) {
  std::string y = kArm;
  auto put = [&](const std::string& k, const std::string& v) { y.replace(y.find(k), k.size(), v); };
  std::string wrist;
  switch (w) {
    case Wrist::Acceleration: wrist = std::string("    order: acceleration\n    expression: ") + kWristAcceleration; break;
    case Wrist::Differentiated:
      wrist = std::string("    order: jerk\n    differentiate: true\n    expression: ") + kWristAcceleration;
      break;
    case Wrist::ByHand: wrist = std::string("    order: jerk\n    expression: ") + kWristJerk; break;
  }
  put("@WRIST@", wrist);
  put("@FORCES@", forces);
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", step);
  put("@STEP@", b);
  std::snprintf(b, sizeof b, "%.17g", t1);
  put("@T1@", b);
  put("@QDD@", w == Wrist::Acceleration ? "" : "  qdd: {consistent_with: wrist}");
  if (w == Wrist::Acceleration) put("baumgarte: {kappa: 50}\n", "");
  return y;
}

Plan plan_of(const std::string& yaml) {
  const auto p = io::parse_problem(yaml, "mixed.yaml");
  Plan plan = plan_problem(*p, *p->make_planner());
  EXPECT_TRUE(plan.summary.ok()) << plan.summary.message;
  return plan;
}

double max_q_error(const Plan& a, const Plan& ref, size_t every, size_t ref_every, int n) {
  double e = 0;
  for (size_t k = 0; k * every < a.size() && k * ref_every < ref.size(); ++k)
    e = std::max(e, (a.x[k * every].head(n) - ref.x[k * ref_every].head(n)).cwiseAbs().maxCoeff());
  return e;
}

// A holonomic task row and a jerk row on the same arm against the equivalent lower-order
// problem (the jerk row is the derivative of an acceleration row): the motions agree to
// integration error, with RK4's order 4.
TEST(MixedOrders, HolonomicAndJerkRowsGiveTheAccelerationLevelMotion) {
  const Plan ref = plan_of(arm(Wrist::Acceleration, 1e-4, 2.0));
  ASSERT_EQ(ref.size(), 20001u);
  std::vector<double> err;
  for (double h : {0.004, 0.002, 0.001}) {
    const Plan plan = plan_of(arm(Wrist::Differentiated, h, 2.0));
    ASSERT_NEAR(plan.t.back(), 2.0, 1e-12);
    // q̈0 from initial.qdd: {consistent_with: wrist} is the acceleration-level plan's q̈0.
    EXPECT_TRUE(test::near(plan.qdd[0], ref.qdd[0], 1e-11, 1e-11)) << plan.qdd[0].transpose() << " vs "
                                                                    << ref.qdd[0].transpose();
    const size_t every = static_cast<size_t>(std::lround(0.004 / h)), ref_every = 40;
    err.push_back(max_q_error(plan, ref, every, ref_every, 3));
    double height = 0;
    for (const auto& phi : plan.phi) height = std::max(height, std::abs(phi[0]));
    std::printf("[ mixed ] h = %.4f: max |q - q_ref| = %.3e, max |Phi_height| = %.2e\n", h, err.back(), height);
    EXPECT_LT(height, 1e-6);
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  std::printf("[ mixed ] error ratios %.2f, %.2f (RK4: 16), observed orders %.2f, %.2f\n", r1, r2, std::log2(r1),
              std::log2(r2));
  EXPECT_LT(std::abs(std::log2(r2) - 4), 0.35);
  EXPECT_GT(r1, 10);
  EXPECT_LT(err[2], 1e-7);
}

// max |x_a − x_b| over the plans of a scenario with a formed row (differentiate: true) and of
// one with the hand-written row. The latter has no source: its q̈0 is given per joint (the
// consistent one of the former).
double formed_against_hand_written(const std::string& formed, std::string by_hand) {
  const Plan a = plan_of(formed);
  char qdd[200];
  std::snprintf(qdd, sizeof qdd, "  qdd: {q1: %.17g, q2: %.17g, q3: %.17g}", a.qdd[0][0], a.qdd[0][1], a.qdd[0][2]);
  by_hand.replace(by_hand.find("  qdd: {consistent_with: wrist}"), 31, qdd);
  const Plan b = plan_of(by_hand);
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (size_t k = 0; k < a.size() && k < b.size(); ++k) d = std::max(d, (a.x[k] - b.x[k]).cwiseAbs().maxCoeff());
  return d;
}

// differentiate: true forms the same row as the hand-written derivative: the plans agree to
// rounding, and the check prints the formed row.
TEST(MixedOrders, DifferentiatedRowEqualsTheHandWrittenDerivative) {
  const double d = formed_against_hand_written(arm(Wrist::Differentiated, 0.002, 1.0), arm(Wrist::ByHand, 0.002, 1.0));
  std::printf("[ mixed ] differentiated vs hand-written jerk row: max |x_a - x_b| = %.2e\n", d);
  EXPECT_LT(d, 1e-10);
  // The formed text is a jerk row: linear in the jerks, with the source kept.
  const auto p = io::parse_problem(arm(Wrist::Differentiated, 0.002, 1.0), "mixed.yaml");
  ASSERT_EQ(p->jerk_constraints.size(), 1u);
  EXPECT_EQ(p->jerk_constraints[0]->source_text(), kWristAcceleration);
  EXPECT_NE(p->jerk_constraints[0]->text().find("jz(E)"), std::string::npos) << p->jerk_constraints[0]->text();
  EXPECT_NE(p->jerk_constraints[0]->text().find("qddd(q3)"), std::string::npos);
}

// The same with piecewise functions in the law (abs, max): their derivatives are piecewise
// (GiNaC's sign and if() forms), which the formed row writes in refdyn's syntax (it printed
// GiNaC's internal names, rd_sgn, rd_if_le, and the scenario failed to load).
TEST(MixedOrders, DifferentiatedPiecewiseRowEqualsTheHandWrittenDerivative) {
  const std::string law = "qdd(q3) + 0.4*abs(q(q2))*az(E) + 0.2*max(qd(q1), 0.1)*ay(E) - 1.2*cos(2*t)";
  const std::string jerk = "qddd(q3) + 0.4*abs(q(q2))*jz(E) + 0.4*if(q(q2) < 0, -1, 1)*qd(q2)*az(E) + "
                           "0.2*max(qd(q1), 0.1)*jy(E) + 0.2*if(qd(q1) >= 0.1, qdd(q1), 0)*ay(E) + 2.4*sin(2*t)";
  auto with = [](std::string y, const std::string& from, const std::string& to) {
    y.replace(y.find(from), from.size(), to);
    return y;
  };
  const std::string formed = with(arm(Wrist::Differentiated, 0.002, 1.0), kWristAcceleration, law);
  const double d = formed_against_hand_written(formed, with(arm(Wrist::ByHand, 0.002, 1.0), kWristJerk, jerk));
  std::printf("[ mixed ] piecewise law: differentiated vs hand-written jerk row: max |x_a - x_b| = %.2e\n", d);
  EXPECT_LT(d, 1e-10);
  const auto p = io::parse_problem(formed, "mixed.yaml");
  ASSERT_EQ(p->jerk_constraints.size(), 1u);
  const std::string text = p->jerk_constraints[0]->text();
  for (const char* frag : {"abs(q(q2))", "max(qd(q1), 0.1)", "if(q(q2) < 0, -1, 1)", "if(0.1 <= qd(q1), 1, 0)"})
    EXPECT_NE(text.find(frag), std::string::npos) << frag << " in " << text;
  EXPECT_EQ(text.find("rd_"), std::string::npos) << text;
}

// Force elements with states (LuGre) in a jerk problem: z is part of the state, its rate exact.
// Over a span without velocity reversals (LuGre's |q̇| is smooth there) the jerk plan agrees with
// the acceleration-level plan to integration error; the drive's signals are recorded.
TEST(MixedOrders, StatefulForcesAndDriveSignalsInJerkPlans) {
  const std::string forces = std::string(kSmoothForces) +
                             "  - {type: lugre, joint: q1, mu_s: 0.1, mu_k: 0.2, sigma0: 50, sigma1: 1, sigma2: 0.1, "
                             "stribeck_velocity: 0.175}\n";
  const Plan ref = plan_of(arm(Wrist::Acceleration, 1e-4, 0.4, forces));
  const Plan plan = plan_of(arm(Wrist::Differentiated, 0.001, 0.4, forces));
  for (const auto& x : ref.x) ASSERT_GT(x[3], 0.0) << "q1 must not reverse in this window";
  EXPECT_EQ(plan.state_names, (std::vector<std::string>{"acc_q1", "acc_q2", "acc_q3", "z_q1"}));
  EXPECT_EQ(plan.x[0].size(), 10);
  const double e = max_q_error(plan, ref, 1, 10, 3);
  double ez = 0;
  for (size_t k = 0; k < plan.size(); ++k) ez = std::max(ez, std::abs(plan.x[k][9] - ref.x[10 * k][6]));
  std::printf("[ mixed ] with LuGre: max |q - q_ref| = %.2e, max |z - z_ref| = %.2e (h = 1e-3, 0.4 s)\n", e, ez);
  EXPECT_LT(e, 1e-8);
  EXPECT_LT(ez, 1e-8);
  ASSERT_EQ(plan.force_signals, ref.force_signals);
  ASSERT_FALSE(plan.force_signals.empty());
  for (size_t k = 0; k < plan.size(); ++k) EXPECT_TRUE(test::near(plan.forces[k], ref.forces[10 * k], 1e-6, 1e-6));
  const io::CsvTable table = io::trajectory_table(plan);
  for (const char* col : {"psi_dr", "tau_drive", "z_q1", "acc_q1", "phi_height", "lambda_wrist"})
    EXPECT_NE(std::find(table.header.begin(), table.header.end(), col), table.header.end()) << col;
}

// Closed form: a point mass on a line (two prismatic joints, a holonomic row keeping it on
// y = x/2) with a prescribed jerk along the line, s⃛ = J sin ωt:
//   s(t) = s0 + v0 t + a0 t²/2 + J (t²/(2ω) + (cos ωt − 1)/ω³).
TEST(MixedOrders, PointMassWithPrescribedJerkFollowsTheClosedForm) {
  const std::string yaml = R"(
name: jerk_line
parameters: {J: 0.9, w: 2.0, m: 1.3}
model:
  gravity: [0, -9.81, 0]
  links:
    - {name: cx, joint: x, parent: base, type: prismatic, axis: [1, 0, 0], mass: 0, inertia: [0, 0, 0]}
    - {name: bead, joint: y, parent: cx, type: prismatic, axis: [0, 1, 0], mass: m, inertia: [0, 0, 0]}
  points:
    P: {link: bead, position: [0, 0, 0]}
forces:
  - {type: damping, joint: x, coefficient: 0.4}
constraints:
  - {name: line, expression: y(P) - x(P)/2}
  - name: jerk
    order: jerk
    expression: (2*jx(P) + jy(P))/sqrt(5) - J*sin(w*t)
initial:
  q: {x: 0.2, y: 0.1}
  qd: {x: 0.4, y: 0.2}
  qdd: {x: 0.6, y: 0.3}
integrator: {method: rk4, step: @H@, t0: 0, t1: 3}
)";
  const double J = 0.9, w = 2.0, s0 = std::sqrt(0.05), v0 = std::sqrt(0.2), a0 = std::sqrt(0.45);
  std::vector<double> err;
  for (double h : {0.01, 0.005, 0.0025}) {
    std::string y = yaml;
    y.replace(y.find("@H@"), 3, std::to_string(h));
    const Plan plan = plan_of(y);
    double e = 0;
    for (size_t k = 0; k < plan.size(); ++k) {
      const double t = plan.t[k], c = std::cos(w * t);
      const double s = s0 + v0 * t + a0 * t * t / 2 + J * (t * t / (2 * w) + (c - 1) / (w * w * w));
      const double v = v0 + a0 * t + J * (t / w - std::sin(w * t) / (w * w));
      const double a = a0 + J * (1 - c) / w;
      const Eigen::Vector2d u(2 / std::sqrt(5.0), 1 / std::sqrt(5.0));
      const Eigen::VectorXd& x = plan.x[k];
      e = std::max({e, (x.head(2) - s * u).cwiseAbs().maxCoeff(), (x.segment(2, 2) - v * u).cwiseAbs().maxCoeff(),
                    (x.segment(4, 2) - a * u).cwiseAbs().maxCoeff()});
    }
    err.push_back(e);
    std::printf("[ mixed ] jerk on a line, h = %.4f: max error in position, speed, acceleration = %.3e\n", h, e);
  }
  EXPECT_LT(err[2], 1e-9);
  const double r = err[1] / err[2];
  EXPECT_GT(r, 12);
  EXPECT_LT(r, 24);
}

// Tracking experiments follow a jerk plan (q̂, q̂̇, q̂̈ of the plan): an exact plant from the plan's
// initial state tracks to integration error, under RK4 (the plan's stages) and Dormand–Prince
// (planner integrated jointly).
TEST(MixedOrders, TrackingFollowsAJerkPlan) {
  for (const std::string method : {"rk4, step: 0.002", "dopri5, rtol: 1e-10, atol: 1e-12, step: 0.01"}) {
    std::string y = arm(Wrist::Differentiated, 0.002, 1.0);
    y.replace(y.find("rk4, step: 0.002"), 16, method);
    y += "controller: {type: computed_torque_pd, delta: {q1: 20, q2: 20, q3: 20}}\n"
         "experiments:\n  - {name: exact, initial: {qd: {q1: qd10, q2: (a - c3*qd30)/c2, q3: qd30}}}\n";
    const auto p = io::parse_problem(y, "mixed.yaml");
    io::RunOptions o;
    o.track = true;
    const io::Results r = io::run_problem(*p, o);
    ASSERT_TRUE(r.ok()) << r.plan.summary.message;
    ASSERT_EQ(r.runs.size(), 1u);
    const ClosedLoopResult& run = r.runs[0].result;
    double e = 0;
    for (size_t k = 0; k < run.size(); ++k) e = std::max(e, (run.x[k].head(3) - run.q_ref[k]).cwiseAbs().maxCoeff());
    std::printf("[ mixed ] tracking a jerk plan (%s): max |q - q_ref| = %.2e\n", method.c_str(), e);
    EXPECT_LT(e, 1e-6);
    EXPECT_NEAR(run.t.back(), 1.0, 1e-9);
  }
}

// A velocity row formed from a position expression (differentiate: true) is the holonomic
// row's Φ̇ with its Jacobian: c = Φ̇, A equal.
TEST(MixedOrders, DifferentiatedVelocityRowIsThePositionRowsRate) {
  const std::string y = arm(Wrist::Acceleration, 0.01, 0.1);
  std::string v = y;
  const std::string row = "  - name: height\n    expression: z(E) - z0 - a*sin(t)\n";
  ASSERT_NE(v.find(row), std::string::npos);
  v.replace(v.find(row), row.size(),
            "  - {name: height, order: velocity, differentiate: true, expression: z(E) - z0 - a*sin(t)}\n");
  const auto p = io::parse_problem(y, "mixed.yaml");
  const auto pv = io::parse_problem(v, "mixed_v.yaml");
  EXPECT_EQ(p->constraints.row_order(0), 0);
  EXPECT_EQ(pv->constraints.row_order(0), 1);
  Data data(p->model), data_v(pv->model);
  ConstraintEval ev(p->model, p->constraints), evv(pv->model, pv->constraints);
  std::mt19937 rng(3);
  for (int k = 0; k < 5; ++k) {
    const Eigen::VectorXd q = test::random_vector(rng, 3, 1.0), qd = test::random_vector(rng, 3, 1.0);
    evaluate_constraints(p->model, data, p->constraints, ev, 0.3 * k, q, qd);
    evaluate_constraints(pv->model, data_v, pv->constraints, evv, 0.3 * k, q, qd);
    EXPECT_NEAR(evv.phi[0], ev.phid[0], 1e-12);
    EXPECT_TRUE(test::near(Eigen::VectorXd(evv.A.row(0).transpose()), Eigen::VectorXd(ev.A.row(0).transpose()), 1e-12,
                           1e-12));
    EXPECT_NEAR(evv.gamma[0], ev.gamma[0], 1e-12);  // ċ = Φ̈: the same drift
  }
  // Bad: differentiate with order position.
  std::string bad = v;
  bad.replace(bad.find("order: velocity, "), 17, "");
  test::expect_error_mentioning([&] { io::parse_problem(bad, "b.yaml"); },
                                {"b.yaml:", "constraints.height.differentiate", "order: position"});
}

}  // namespace
}  // namespace refdyn
