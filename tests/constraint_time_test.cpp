// Time as a dual number in the constraints' evaluation (issue 22): evaluate_constraints_dual with a
// seeded t gives the total time derivatives of Φ, Φ̇, A and γ along a motion, ∂/∂t of the
// rheonomic rows included; for that every time function has an exact f''' (TimeValue::dddf).
//  (1) f''' of every kind of time function (constant, polynomial, sinusoid, raised cosine,
//      cycloidal, expressions in t with and without kinks) against central differences of f'',
//      and eval_dual(f, t) against f', f'', f''' (an unseeded t: derivative parts exactly +0);
//      ExpressionOptions::differentiate_times against the hand derivative;
//  (2) every constraint kind (the ready-made ones of test_support's all_kinds, rheonomic rows
//      with time functions of every type, expression rows of orders 0, 1 and 2 that use t, the
//      distance kind, the example scenarios), seeded in one direction with t ← 1, q ← q̇,
//      q̇ ← q̈: the derivative parts of phi, phid, A and gamma against central differences of
//      evaluate_constraints along (t + h, q + h q̇ + h²/2 q̈, q̇ + h q̈); in a second direction
//      t ← 1 alone (∂/∂t) against differences in t; the unseeded directions stay 0; the value
//      parts equal evaluate_constraints.
//
// FD budget, (2): h = 1e-5 on the path; truncation h²|F'''|/6 ≈ 2e-11 |F'''| and rounding
// ε|F|/h ≈ 2e-11 |F| with |F|, |F'''| ≲ 1e3 here: ≲ 1e-8. Tolerance: 1e-7 relative to the row's
// size (at least 1): a row's entry d is compared as |d − fd| ≤ 1e-7 max(1, max|fd| of the row).
// (1): h = 1e-5 on f'': the same budget with f'' ≲ 1e2.
#include "refdyn/common/dual.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_function.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

using namespace refdyn;

namespace {

using JS = JacobianScalar;
constexpr int kDir = kJacobianDirections;

// ---------------------------------------------------------------------------------------------
// (1) time functions
// ---------------------------------------------------------------------------------------------
struct NamedFunction {
  std::string label;
  TimeFunctionPtr f;
  double lo, hi;                    // where t is drawn
  std::vector<double> switches;     // where f''' jumps: no stencil straddles them
};

std::vector<NamedFunction> function_zoo() {
  return {
      {"constant", constant(2.5), -1, 4, {}},
      {"polynomial", polynomial({0.3, -1.2, 0.7, 0.25, -0.05, 0.01}), -2, 3, {}},
      {"polynomial cubic", polynomial({0.1, 0.2, 0.3, 0.4}), -2, 3, {}},
      {"polynomial empty", polynomial({}), -1, 1, {}},
      {"sinusoid", sinusoid(0.8, 3.1, 0.4, -0.2), -1, 4, {}},
      {"raised cosine", raised_cosine(1.0, 0.1, 5.0), -1, 6, {}},
      {"raised cosine fast", raised_cosine(-0.4, 2.0, 0.7), -1, 2, {}},
      {"cycloidal", cycloidal(2 * std::numbers::pi, 5.0), -1, 6, {0.0, 5.0}},
      {"cycloidal shifted", cycloidal(-1.5, 0.8, 0.3, 0.6), 0, 2, {0.6, 1.4}},
      {"expression smooth", expression_time_function("z0 + dz*(1 - cos(2*pi*t/T))/2 + 0.1*exp(-t)*sin(3*t) + t^4/24",
                                                     {{"z0", 0.2}, {"dz", 0.3}, {"T", 1.7}}),
       -1, 3, {}},
      {"expression functions", expression_time_function("sqrt(2 + t^2) + atan(t) + log(3 + sin(t)) + tanh(0.5*t)*cosh(0.2*t)"),
       -2, 2, {}},
      {"expression kinks", expression_time_function("if(t < 1.5, t^3, 3.375 + 6.75*(t - 1.5)) + min(t, 2)^4 + abs(t - 0.5)^3"),
       -1, 3, {0.5, 1.5, 2.0}},
      {"expression clamp", expression_time_function("(1 - cos(pi*clamp(t, 0, 2)/2))/2"), -1, 3, {0.0, 2.0}},
      {"expression constant in t", expression_time_function("a*sin(t) + 3", {{"a", 0.0}}), -1, 1, {}},
  };
}

TEST(TimeFunctionThirdDerivative, MatchesCentralDifferencesOfTheSecond) {
  std::mt19937 rng(22);
  const double h = 1e-5;
  double worst = 0;
  int compared = 0;
  for (const NamedFunction& n : function_zoo()) {
    std::uniform_real_distribution<double> ut(n.lo, n.hi);
    for (int k = 0; k < 60; ++k) {
      const double t = ut(rng);
      bool near_switch = false;
      for (double s : n.switches) near_switch = near_switch || std::fabs(t - s) < 1e-3;
      if (near_switch) continue;
      const TimeValue v = n.f->eval(t);
      const double fd = (n.f->eval(t + h).ddf - n.f->eval(t - h).ddf) / (2 * h);
      const double scale = std::max(1.0, std::fabs(fd));
      EXPECT_NEAR(v.dddf, fd, 1e-7 * scale) << n.label << " at t = " << t;
      worst = std::max(worst, std::fabs(v.dddf - fd) / scale);
      ++compared;
    }
  }
  EXPECT_GT(compared, 700);
  std::printf("f''' of %d samples of %zu functions: worst |f''' - FD(f'')| / max(1, |FD|) = %.2e\n", compared,
              function_zoo().size(), worst);
}

TEST(TimeFunctionThirdDerivative, ClosedFormsAndConstantBranches) {
  // Exact values where they are known in closed form.
  const double t = 0.73, w = 3.1, a = 0.8, p = 0.4;
  EXPECT_DOUBLE_EQ(sinusoid(a, w, p, -0.2)->eval(t).dddf, -a * w * w * w * std::cos(w * t + p));
  EXPECT_EQ(polynomial({1, 2, 3, 4})->eval(t).dddf, 24.0);
  EXPECT_EQ(polynomial({1, 2, 3})->eval(t).dddf, 0.0);
  EXPECT_DOUBLE_EQ(polynomial({0, 0, 0, 0, 1})->eval(t).dddf, 24 * t);
  EXPECT_EQ(constant(4.0)->eval(t).dddf, 0.0);
  EXPECT_DOUBLE_EQ(expression_time_function("t^5")->eval(t).dddf, 60 * t * t);
  EXPECT_DOUBLE_EQ(expression_time_function("k*t^3", {{"k", 2.0}})->eval(-1.3).dddf, 12.0);
  // The cycloidal rise: constant outside [t0, t0 + duration], 4π² rise/duration³ cos 2πτ inside.
  const auto c = cycloidal(1.5, 0.8, 0.3, 0.6);
  EXPECT_EQ(c->eval(0.2).dddf, 0.0);
  EXPECT_EQ(c->eval(1.6).dddf, 0.0);
  const double tau = (1.0 - 0.6) / 0.8;
  EXPECT_NEAR(c->eval(1.0).dddf, 4 * std::numbers::pi * std::numbers::pi * 1.5 / (0.8 * 0.8 * 0.8) *
                                     std::cos(2 * std::numbers::pi * tau), 1e-12);
  // An expression's kinks: the branch's derivatives (if(t < 1.5, t^3, linear): 6 before, 0 after).
  const auto k = expression_time_function("if(t < 1.5, t^3, 3.375 + 6.75*(t - 1.5))");
  EXPECT_EQ(k->eval(1.2).dddf, 6.0);
  EXPECT_EQ(k->eval(1.5).dddf, 0.0);
}

TEST(TimeFunctionThirdDerivative, ExpressionExtraDerivativeOption) {
  ExpressionOptions o;
  o.derivative_order = 1;
  o.extra_derivative_order = 2;
  o.extra_derivative_variable = 1;
  const Expression e("x*y^4 + sin(y)*x^2", {"x", "y"}, {}, o);  // ∂²/∂y²: 12 x y² − sin(y) x²
  const double xv[2] = {0.7, -1.1};
  double v = 0, g[2];
  e.evaluate(xv, v, g, nullptr);  // the expression itself is unchanged
  EXPECT_NEAR(v, 0.7 * std::pow(1.1, 4) + std::sin(-1.1) * 0.49, 1e-14);
  EXPECT_NEAR(g[1], 4 * 0.7 * std::pow(-1.1, 3) + std::cos(-1.1) * 0.49, 1e-14);
  EXPECT_NEAR(e.extra_derivative(xv), 12 * 0.7 * 1.21 - std::sin(-1.1) * 0.49, 1e-14);
  EXPECT_FALSE(e.extra_derivative_text().empty());
  // Without the option: a clear error. Bad options: errors naming them.
  const Expression plain("x + y", {"x", "y"});
  test::expect_error_mentioning([&] { plain.extra_derivative(xv); }, {"extra_derivative", "built without one"});
  ExpressionOptions bad = o;
  bad.extra_derivative_variable = 2;
  test::expect_error_mentioning([&] { Expression("x + y", {"x", "y"}, {}, bad); },
                                {"extra_derivative_variable", "0..1", "2"});
  bad.extra_derivative_variable = 0;
  bad.extra_derivative_order = -1;
  test::expect_error_mentioning([&] { Expression("x + y", {"x", "y"}, {}, bad); }, {"extra_derivative_order", ">= 0"});
}

TEST(TimeFunctionThirdDerivative, EvalDualCarriesTheNextDerivatives) {
  for (const NamedFunction& n : function_zoo()) {
    const double t = 0.5 * (n.lo + n.hi) + 0.123;
    const TimeValue v = n.f->eval(t);
    JS ts(t);
    ts.d[0] = 1.0;
    ts.d[3] = -2.5;
    const TimeValueDual d = eval_dual(*n.f, ts);
    EXPECT_EQ(d.f.v, v.f) << n.label;
    EXPECT_EQ(d.df.v, v.df) << n.label;
    EXPECT_EQ(d.ddf.v, v.ddf) << n.label;
    EXPECT_EQ(d.f.d[0], v.df) << n.label;
    EXPECT_EQ(d.df.d[0], v.ddf) << n.label;
    EXPECT_EQ(d.ddf.d[0], v.dddf) << n.label;
    EXPECT_EQ(d.ddf.d[3], -2.5 * v.dddf) << n.label;
    EXPECT_EQ(d.f.d[1], 0.0) << n.label;
    // Unseeded: the constants of the double-time code, derivative parts +0 (no −0).
    const TimeValueDual u = eval_dual(*n.f, JS(t));
    for (const JS* x : {&u.f, &u.df, &u.ddf})
      for (int k = 0; k < kDir; ++k) EXPECT_TRUE(x->d[k] == 0.0 && !std::signbit(x->d[k])) << n.label;
  }
}

// ---------------------------------------------------------------------------------------------
// (2) constraints along a motion
// ---------------------------------------------------------------------------------------------
struct Plain {
  Eigen::VectorXd phi, phid, gamma;
  Eigen::MatrixXd A;
};

Plain eval_double(const Model& model, const ConstraintSet& set, double t, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& qd) {
  Data data(model);
  ConstraintEval ev(model, set);
  evaluate_constraints(model, data, set, ev, t, q, qd);
  return {ev.phi, ev.phid, ev.gamma, ev.A};
}

Plain scaled_difference(const Plain& p, const Plain& m, double inv) {
  return {(p.phi - m.phi) * inv, (p.phid - m.phid) * inv, (p.gamma - m.gamma) * inv, (p.A - m.A) * inv};
}

/// Direction k of the dual results, or their values for k < 0.
Plain part(const ConstraintEvalDual& ev, int k) {
  const int m = ev.m, n = ev.n;
  Plain out{Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::VectorXd(m), Eigen::MatrixXd(m, n)};
  auto get = [k](const JS& x) { return k < 0 ? x.v : x.d[k]; };
  for (int r = 0; r < m; ++r) {
    out.phi[r] = get(ev.phi[r]);
    out.phid[r] = get(ev.phid[r]);
    out.gamma[r] = get(ev.gamma[r]);
    for (int j = 0; j < n; ++j) out.A(r, j) = get(ev.A[static_cast<size_t>(r) * n + j]);
  }
  return out;
}

struct Worst {
  double total = 0, partial_t = 0;
};

/// Row by row: |d − fd| ≤ tol · max(1, max |fd| of the row); the worst ratio into `worst`.
void expect_rows_near(const ConstraintSet& set, const Plain& d, const Plain& fd, double tol, const std::string& where,
                      double& worst) {
  auto check = [&](const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const char* what) {
    for (Eigen::Index r = 0; r < a.rows(); ++r) {
      const double scale = std::max(1.0, b.row(r).cwiseAbs().maxCoeff());
      const double err = (a.row(r) - b.row(r)).cwiseAbs().maxCoeff();
      worst = std::max(worst, err / scale);
      EXPECT_LE(err, tol * scale) << where << ": " << what << " of row " << set.row_name(static_cast<int>(r))
                                  << " (order " << set.row_order(static_cast<int>(r)) << "): dual "
                                  << a.row(r) << " vs FD " << b.row(r);
    }
  };
  check(d.phi, fd.phi, "phi");
  check(d.phid, fd.phid, "phid");
  check(d.gamma, fd.gamma, "gamma");
  check(d.A, fd.A, "A");
}

/// One state (t, q, q̇) and a q̈: direction 0 seeded with t ← 1, q ← q̇, q̇ ← q̈ (the motion),
/// direction 1 with t ← 1 alone; both against central differences. Returns the entries compared.
int check_motion(const Model& model, const ConstraintSet& set, double t, const Eigen::VectorXd& q,
                 const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd, const std::string& label, Worst& worst) {
  const int n = model.nv;
  ConstraintEvalDual ev(model, set);
  std::vector<JS> qs(n), qds(n);
  for (int i = 0; i < n; ++i) {
    qs[i] = JS(q[i]);
    qs[i].d[0] = qd[i];
    qds[i] = JS(qd[i]);
    qds[i].d[0] = qdd[i];
  }
  JS ts(t);
  ts.d[0] = 1.0;
  ts.d[1] = 1.0;
  evaluate_constraints_dual(model, set, ev, ts, qs.data(), qds.data());

  const Plain ref = eval_double(model, set, t, q, qd);
  const Plain val = part(ev, -1);
  const double tv = 1e-12;
  EXPECT_TRUE(test::near(val.phi, ref.phi, tv, tv)) << label << ": phi";
  EXPECT_TRUE(test::near(val.phid, ref.phid, tv, tv)) << label << ": phid";
  EXPECT_TRUE(test::near(val.gamma, ref.gamma, tv, tv * std::max(1.0, ref.gamma.cwiseAbs().maxCoeff())))
      << label << ": gamma";
  EXPECT_TRUE(test::near(val.A, ref.A, tv, tv)) << label << ": A";

  const double h = 1e-5;
  auto at = [&](double s) {
    return eval_double(model, set, t + s, q + s * qd + 0.5 * s * s * qdd, qd + s * qdd);
  };
  const Plain total_fd = scaled_difference(at(h), at(-h), 0.5 / h);
  expect_rows_near(set, part(ev, 0), total_fd, 1e-7, label + ", d/dt along the motion", worst.total);
  const Plain partial_fd = scaled_difference(eval_double(model, set, t + h, q, qd), eval_double(model, set, t - h, q, qd),
                                             0.5 / h);
  expect_rows_near(set, part(ev, 1), partial_fd, 1e-7, label + ", partial d/dt", worst.partial_t);
  for (int k = 2; k < kDir; ++k) {
    const Plain z = part(ev, k);
    EXPECT_TRUE(z.phi.isZero(0) && z.phid.isZero(0) && z.gamma.isZero(0) && z.A.isZero(0))
        << label << ": unseeded direction " << k << " is not zero";
  }
  return 2 * (3 * set.rows() + set.rows() * n);
}

/// random_chain's tip plus "mid" on a middle link and "anchor" in the world (all_kinds' points);
/// the zoo without fixed links.
std::vector<test::RandomModelCase> model_zoo(std::mt19937& rng, int dof) {
  test::ZooOptions o;
  o.variants = 4;
  o.dof_in_label = true;
  return test::model_zoo(rng, dof, o);
}

/// Rheonomic rows with time functions of every type, and expression rows of orders 0, 1, 2 in t.
ConstraintSet rheonomic_kinds(const Model& model, std::mt19937& rng) {
  const std::string j0 = model.joint_name[0], j1 = model.joint_name[model.nq - 1],
                    jm = model.joint_name[model.nq / 2];
  ConstraintSet set;
  set.add(test::renamed(point_coordinate(model, "mid", 1, cycloidal(0.4, 2.0, 0.1, 0.3)), "y_mid_cycloidal"));
  set.add(test::renamed(point_coordinate(model, "tip", 2, constant(0.3)), "z_tip_constant"));
  set.add(test::renamed(point_coordinate(model, "tip", 0, polynomial({0.1, -0.2, 0.3, 0.15, -0.04})), "x_tip_poly"));
  set.add(test::renamed(
      joint_trajectory(model, j1,
                       expression_time_function("a*sin(w*t) + if(t < T, t^3, T^3 + 3*T^2*(t - T)) + exp(-t)*cos(2*t)",
                                                {{"a", 0.3}, {"w", 1.7}, {"T", 1.5}})),
      "q_expression"));
  set.add(test::renamed(joint_trajectory(model, jm, raised_cosine(0.2, 0.5, 1.9)), "q_raised_cosine"));
  set.add(test::renamed(point_speed(model, "tip", test::random_unit(rng), raised_cosine(0.2, 0.3, 2.5)),
                        "speed_raised_cosine"));
  set.add(test::renamed(point_speed(model, "mid", test::random_unit(rng),
                                    expression_time_function("0.2*t^3 - 0.1*sin(4*t)")),
                        "speed_expression"));
  set.add(test::renamed(point_on_surface(model, "mid", plane(test::random_unit(rng), polynomial({0.2, 0.1, -0.3, 0.2}))),
                        "plane_poly"));
  set.add(test::renamed(point_on_surface(model, "anchor", plane(Vec3(0, 0, 1), expression_time_function("0.8 + 0*t"))),
                        "plane_world_point"));  // a world point: A = 0, Φ constant
  set.add(test::renamed(point_on_surface(model, "tip", plane(test::random_unit(rng), cycloidal(-0.3, 1.6, 0.4, 0.2))),
                        "plane_cycloidal"));
  set.add(expression_constraint(
      model, "expr_position_t",
      "x(tip)*cos(t) + sin(q(" + j0 + ") + 0.5*t)*exp(-0.2*t) + if(t < 1.5, t^2, 3*t - 2.25)*y(mid) + "
      "sqrt(1 + (z(tip) - t)^2) + atan2(y(tip) + t, 4) - 0.4",
      false));
  set.add(expression_constraint(model, "expr_joint_t", "q(" + j0 + ") - 0.3*sin(1.3*t) + t^3*q(" + j1 + ")", false));
  set.add(expression_constraint(
      model, "expr_velocity_t",
      "vx(tip)*sin(2*t) + qd(" + j1 + ")*exp(0.1*t*q(" + j0 + ")) + t*vy(mid) + x(mid)*t^2 - cos(t)", true));
  set.add(expression_constraint(
      model, "expr_acceleration_t",
      "ax(tip)*cos(t) + qdd(" + j1 + ")*(1 + 0.2*sin(3*t)) + t*az(mid)*qd(" + j0 + ") + exp(-t)*vy(tip) "
      "+ t^2*y(tip)*qdd(" + j0 + ") - 1.2*cos(2*t)",
      ConstraintOrder::Acceleration));
  set.add(expression_constraint(model, "expr_acceleration_scleronomic",
                                "qdd(" + j0 + ") + 0.4*cos(q(" + j1 + "))*az(tip) + 0.2*qd(" + jm + ")*ay(mid)",
                                ConstraintOrder::Acceleration));
  return set;
}

/// t away from the kinks of rheonomic_kinds (the cycloidal ends 0.2, 0.3, 1.8, 2.3; t = 1.5).
double draw_time(std::mt19937& rng) {
  const double u = std::uniform_real_distribution<double>(0.0, 1.0)(rng);
  return u < 0.6 ? 0.4 + u / 0.6 * 1.0 : 1.6 + (u - 0.6) / 0.4 * 0.15;
}

}  // namespace

TEST(ConstraintTimeDerivative, EveryReadyMadeKindAlongAMotion) {
  std::mt19937 rng(2022);
  Worst worst;
  int compared = 0;
  for (int dof : {4, 7})
    for (const auto& [label, desc] : model_zoo(rng, dof)) {
      const Model model = build_model(desc);
      const ConstraintSet set = test::all_kinds(model, rng);
      for (int trial = 0; trial < 3; ++trial) {
        const Eigen::VectorXd q = test::random_vector(rng, model.nq, 3.0), qd = test::random_vector(rng, model.nq, 2.0),
                              qdd = test::random_vector(rng, model.nq, 2.0);
        compared += check_motion(model, set, draw_time(rng), q, qd, qdd, label + " trial " + std::to_string(trial), worst);
      }
    }
  EXPECT_GT(compared, 5000);
  std::printf("ready-made kinds: %d entries, worst |d - FD| / row scale: along the motion %.2e, partial d/dt %.2e\n",
              compared, worst.total, worst.partial_t);
}

TEST(ConstraintTimeDerivative, RheonomicRowsOfEveryTimeFunctionAndExpressionOrder) {
  std::mt19937 rng(522);
  Worst worst;
  int compared = 0;
  for (int dof : {3, 6})
    for (const auto& [label, desc] : model_zoo(rng, dof)) {
      const Model model = build_model(desc);
      const ConstraintSet set = rheonomic_kinds(model, rng);
      for (int k = 0; k < set.size(); ++k) {
        if (set.constraints()[k]->name != "expr_acceleration_scleronomic") {
          EXPECT_TRUE(set.constraints()[k]->rheonomic()) << set.constraints()[k]->name;
        }
      }
      for (int trial = 0; trial < 4; ++trial) {
        const Eigen::VectorXd q = test::random_vector(rng, model.nq, 2.0), qd = test::random_vector(rng, model.nq, 1.5),
                              qdd = test::random_vector(rng, model.nq, 2.0);
        compared += check_motion(model, set, draw_time(rng), q, qd, qdd, label + " trial " + std::to_string(trial), worst);
      }
    }
  std::printf("rheonomic rows: %d entries, worst |d - FD| / row scale: along the motion %.2e, partial d/dt %.2e\n",
              compared, worst.total, worst.partial_t);
}

TEST(ConstraintTimeDerivative, DistanceKindAndExampleScenarios) {
  const std::string yaml = R"(name: two_link
parameters: {L: 0.5, d0: 0.8, dd: 0.15, T: 2}
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: l1, joint: q1, parent: base, type: revolute, axis: [0, 0, 1], mass: 1, com: [0.25, 0, 0], inertia: [0.001, 0.02, 0.02]}
    - {name: l2, joint: q2, parent: l1, type: revolute, axis: [0.3, 0.2, 1], origin: {xyz: [0.5, 0, 0.1]}, mass: 1, com: [0.25, 0, 0], inertia: [0.001, 0.02, 0.02]}
    - {name: l3, joint: q3, parent: l2, type: prismatic, axis: [1, 0, 0.2], origin: {xyz: [0.5, 0, 0]}, mass: 1, com: [0.25, 0, 0], inertia: [0.001, 0.02, 0.02]}
  points:
    B: {link: world, position: [0.1, -0.2, 0.05]}
    E: {link: l3, position: [0.2, 0.1, 0]}
constraints:
  - {name: reach, kind: distance, points: [B, E], length: d0 + dd*(1 - cos(2*pi*t/T))/2 + 0.05*t^3}
partition: {independent: [q1, q3]}
initial: {q: [0, 1.0, 0.1], consistency: project}
integrator: {method: rk4, step: 1e-3, t1: 2}
)";
  std::mt19937 rng(9);
  {
    const auto problem = io::parse_problem(yaml, "distance.yaml");
    Worst worst;
    for (int trial = 0; trial < 6; ++trial) {
      const Eigen::VectorXd q = test::random_vector(rng, 3, 2.0), qd = test::random_vector(rng, 3, 1.5),
                            qdd = test::random_vector(rng, 3, 2.0);
      check_motion(problem->model, problem->constraints, 0.2 + 0.3 * trial, q, qd, qdd,
                   "distance trial " + std::to_string(trial), worst);
    }
    std::printf("distance: worst along the motion %.2e, partial d/dt %.2e\n", worst.total, worst.partial_t);
  }
  for (const std::string file : {"paper/paper.yaml", "four_bar/four_bar.yaml", "unicycle/unicycle.yaml",
                                 "planar_2r_circle/planar_2r_circle.yaml", "waiter_tray/waiter_tray.yaml",
                                 "urdf_arm_line/urdf_arm_line.yaml",
                                 "planar_2r_circle/retime.yaml"}) {  // times 0.1, 0.47, 0.84: inside parts of its time law
    const auto problem = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/examples/" + file);
    const int n = problem->model.nv;
    Worst worst;
    for (int trial = 0; trial < 3; ++trial) {
      const Eigen::VectorXd q = problem->q0 + (trial ? test::random_vector(rng, n, 0.3) : Eigen::VectorXd::Zero(n));
      const Eigen::VectorXd qd = problem->qd0 + test::random_vector(rng, n, 0.5), qdd = test::random_vector(rng, n, 1.0);
      check_motion(problem->model, problem->constraints, 0.1 + 0.37 * trial, q, qd, qdd,
                   file + " trial " + std::to_string(trial), worst);
    }
    std::printf("%s: %d rows, worst along the motion %.2e, partial d/dt %.2e\n", file.c_str(),
                problem->constraints.rows(), worst.total, worst.partial_t);
  }
}

TEST(ConstraintTimeDerivative, AnUnseededTimeGivesPositiveZeroParts) {
  // The double-t callers (reference Jacobian, closed loop) pass t as a plain double, which
  // converts to an unseeded time: the rheonomic terms' derivative parts are then +0, as the
  // constants of the double-time code were (no −0 from a negated constant).
  std::mt19937 rng(1);
  const Model model = build_model(test::random_chain(rng, {.dof = 5}));
  const int n = model.nv;
  ConstraintSet set;
  set.add(joint_trajectory(model, model.joint_name[0], polynomial({0.1, 0.2, 0.3})));
  set.add(joint_trajectory(model, model.joint_name[1], raised_cosine(0.1, 0.2, 1.3)));
  set.add(joint_trajectory(model, model.joint_name[2], expression_time_function("sin(3*t) - t^3")));
  ConstraintEvalDual e(model, set);
  std::vector<JS> q0(n, JS(0.1)), qd0(n, JS(0.2));
  evaluate_constraints_dual(model, set, e, 0.5, q0.data(), qd0.data());
  for (int r = 0; r < set.rows(); ++r)
    for (int k = 0; k < kDir; ++k)
      for (const JS* x : {&e.phi[r], &e.phid[r], &e.gamma[r]})
        EXPECT_TRUE(x->d[k] == 0.0 && !std::signbit(x->d[k])) << set.row_name(r) << " direction " << k;
}
