// Exact derivatives of the constraints over dual numbers (issue 21): evaluate_constraints_dual
// and every kind's evaluate_dual, for the implicit integrator's exact Jacobian ∂f/∂x.
//  (0) the dual-number functions of common/dual.hpp against central finite differences;
//  (1) the value parts of evaluate_constraints_dual equal evaluate_constraints (1e-12 relative);
//  (2) the derivative parts, seeded with q_j and then q̇_j, equal central finite differences of
//      evaluate_constraints' Φ, Φ̇, A and γ (relative 1e-7, absolute floor 1e-7 × the largest
//      entry of that block, at least 1e-7);
//  (3) expression constraints of orders 0, 1 and 2 with sin, cos, exp, sqrt, pow, atan2 (and
//      min, abs) in them, through the dual tape;
//  (4) a kind without evaluate_dual throws an Error naming it.
// Models: the random chains and trees of constraints_test (every ready-made kind), the distance
// kind on a 2R arm, and the example scenarios (paper arm, four-bar, unicycle, …).
//
// FD budget (central, h = 1e-6 (1 + |x|)): truncation h²|f'''|/6 ≲ 1e-11 |f'''|, rounding
// ε|f|/h ≲ 1e-10 |f|: the tolerance 1e-7 keeps three orders of magnitude above both.
#include "refdyn/common/dual.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

using namespace refdyn;
using refdyn::test::near;

namespace {

using JS = JacobianScalar;
constexpr int kDir = kJacobianDirections;

// ---------------------------------------------------------------------------------------------
// (0) dual numbers
// ---------------------------------------------------------------------------------------------
using D1 = ad::Dual<1>;

struct UnaryCase {
  const char* name;
  std::function<D1(const D1&)> fd;
  std::function<double(double)> f;
  std::vector<double> at;
};

TEST(DualNumbers, EveryFunctionMatchesCentralDifferences) {
  const std::vector<UnaryCase> cases = {
      {"sin", [](const D1& x) { return sin(x); }, [](double x) { return std::sin(x); }, {-2.1, 0.3, 1.7}},
      {"cos", [](const D1& x) { return cos(x); }, [](double x) { return std::cos(x); }, {-2.1, 0.3, 1.7}},
      {"sqrt", [](const D1& x) { return sqrt(x); }, [](double x) { return std::sqrt(x); }, {0.2, 1.0, 7.5}},
      {"exp", [](const D1& x) { return exp(x); }, [](double x) { return std::exp(x); }, {-1.5, 0.0, 2.3}},
      {"log", [](const D1& x) { return log(x); }, [](double x) { return std::log(x); }, {0.2, 1.0, 7.5}},
      {"tan", [](const D1& x) { return tan(x); }, [](double x) { return std::tan(x); }, {-1.2, 0.3, 1.1}},
      {"asin", [](const D1& x) { return asin(x); }, [](double x) { return std::asin(x); }, {-0.8, 0.1, 0.6}},
      {"acos", [](const D1& x) { return acos(x); }, [](double x) { return std::acos(x); }, {-0.8, 0.1, 0.6}},
      {"atan", [](const D1& x) { return atan(x); }, [](double x) { return std::atan(x); }, {-3.0, 0.1, 2.0}},
      {"sinh", [](const D1& x) { return sinh(x); }, [](double x) { return std::sinh(x); }, {-1.5, 0.2, 2.0}},
      {"cosh", [](const D1& x) { return cosh(x); }, [](double x) { return std::cosh(x); }, {-1.5, 0.2, 2.0}},
      {"tanh", [](const D1& x) { return tanh(x); }, [](double x) { return std::tanh(x); }, {-1.5, 0.2, 2.0}},
      {"asinh", [](const D1& x) { return asinh(x); }, [](double x) { return std::asinh(x); }, {-2.0, 0.2, 3.0}},
      {"acosh", [](const D1& x) { return acosh(x); }, [](double x) { return std::acosh(x); }, {1.2, 2.0, 5.0}},
      {"atanh", [](const D1& x) { return atanh(x); }, [](double x) { return std::atanh(x); }, {-0.7, 0.1, 0.8}},
      {"abs", [](const D1& x) { return abs(x); }, [](double x) { return std::fabs(x); }, {-1.3, 0.4}},
      {"pow(x, 2.5)", [](const D1& x) { return pow(x, 2.5); }, [](double x) { return std::pow(x, 2.5); }, {0.3, 1.9}},
      {"pow(x, -3)", [](const D1& x) { return pow(x, -3.0); }, [](double x) { return std::pow(x, -3.0); },
       {-1.4, 0.7, 2.2}},
      {"x / (1 + x x) - x", [](const D1& x) { return x / (D1(1.0) + x * x) - x; },
       [](double x) { return x / (1.0 + x * x) - x; }, {-1.1, 0.5}},
  };
  for (const UnaryCase& c : cases)
    for (double x0 : c.at) {
      const D1 y = c.fd(D1::variable(x0, 0));
      const double h = 1e-6 * (1.0 + std::fabs(x0));
      const double fd = (c.f(x0 + h) - c.f(x0 - h)) / (2 * h);
      EXPECT_DOUBLE_EQ(y.v, c.f(x0)) << c.name << " at " << x0;
      EXPECT_NEAR(y.d[0], fd, 1e-7 * std::max(1.0, std::fabs(fd))) << c.name << " at " << x0;
    }
  // Two arguments, derivatives along both.
  using D2 = ad::Dual<2>;
  const std::vector<std::pair<double, double>> pts = {{0.7, 1.3}, {-0.4, 2.1}, {1.5, -0.6}, {-0.8, -1.9}};
  for (const auto& [a, b] : pts) {
    const D2 y = D2::variable(a, 0), x = D2::variable(b, 1);
    const D2 r = atan2(y, x);
    const double h = 1e-6;
    EXPECT_NEAR(r.d[0], (std::atan2(a + h, b) - std::atan2(a - h, b)) / (2 * h), 1e-7) << "atan2 d/dy";
    EXPECT_NEAR(r.d[1], (std::atan2(a, b + h) - std::atan2(a, b - h)) / (2 * h), 1e-7) << "atan2 d/dx";
    const double base = std::fabs(a) + 0.5, ex = b;  // pow(x, y) needs x > 0 for a variable exponent
    const D2 p = pow(D2::variable(base, 0), D2::variable(ex, 1));
    const double d0 = (std::pow(base + h, ex) - std::pow(base - h, ex)) / (2 * h);
    const double d1 = (std::pow(base, ex + h) - std::pow(base, ex - h)) / (2 * h);
    EXPECT_NEAR(p.d[0], d0, 1e-7 * std::max(1.0, std::fabs(d0))) << "pow d/dx at " << base << ", " << ex;
    EXPECT_NEAR(p.d[1], d1, 1e-7 * std::max(1.0, std::fabs(d1))) << "pow d/dy at " << base << ", " << ex;
  }
  // A constant exponent as a dual with zero derivative: no log of a negative base.
  const D2 q = pow(D2::variable(-1.5, 0), D2(3.0));
  EXPECT_DOUBLE_EQ(q.v, -3.375);
  EXPECT_DOUBLE_EQ(q.d[0], 3 * 2.25);
  EXPECT_EQ(q.d[1], 0.0);
}

// ---------------------------------------------------------------------------------------------
// Dual evaluation against evaluate_constraints and its finite differences
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

/// Values and the 2n directional derivatives (columns: q_0 … q_{n−1}, q̇_0 … q̇_{n−1}) from
/// evaluate_constraints_dual, ⌈2n / kJacobianDirections⌉ sweeps.
struct DualResult {
  Plain value;
  std::vector<Plain> deriv;  // 2n
};

DualResult eval_dual(const Model& model, const ConstraintSet& set, double t, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qd) {
  const int n = model.nv, m = set.rows();
  ConstraintEvalDual ev(model, set);
  DualResult out;
  out.deriv.resize(2 * n);
  std::vector<JS> qs(n), qds(n);
  for (int c0 = 0; c0 < 2 * n; c0 += kDir) {
    for (int i = 0; i < n; ++i) {
      qs[i] = JS(q[i]);
      qds[i] = JS(qd[i]);
      for (int k = 0; k < kDir; ++k) {
        if (c0 + k == i) qs[i].d[k] = 1.0;
        if (c0 + k == n + i) qds[i].d[k] = 1.0;
      }
    }
    evaluate_constraints_dual(model, set, ev, t, qs.data(), qds.data());
    auto val = [&](int k, std::vector<JS>& v, Eigen::VectorXd& out_v) {
      out_v.resize(m);
      for (int r = 0; r < m; ++r) out_v[r] = k < 0 ? v[r].v : v[r].d[k];
    };
    auto mat = [&](int k, Eigen::MatrixXd& out_A) {
      out_A.resize(m, n);
      for (int r = 0; r < m; ++r)
        for (int j = 0; j < n; ++j) out_A(r, j) = k < 0 ? ev.A[r * n + j].v : ev.A[r * n + j].d[k];
    };
    if (c0 == 0) {
      val(-1, ev.phi, out.value.phi);
      val(-1, ev.phid, out.value.phid);
      val(-1, ev.gamma, out.value.gamma);
      mat(-1, out.value.A);
    }
    for (int k = 0; k < kDir && c0 + k < 2 * n; ++k) {
      Plain& d = out.deriv[c0 + k];
      val(k, ev.phi, d.phi);
      val(k, ev.phid, d.phid);
      val(k, ev.gamma, d.gamma);
      mat(k, d.A);
    }
  }
  return out;
}

double floor_of(const Eigen::MatrixXd& a) { return 1e-7 * std::max(1.0, a.size() ? a.cwiseAbs().maxCoeff() : 0.0); }

struct Worst {
  double value = 0, deriv = 0;
};

/// (1) and (2) at one state; returns the number of derivative entries compared.
int check_state(const Model& model, const ConstraintSet& set, double t, const Eigen::VectorXd& q,
                const Eigen::VectorXd& qd, const std::string& label, Worst& worst) {
  const int n = model.nv;
  const Plain ref = eval_double(model, set, t, q, qd);
  const DualResult dr = eval_dual(model, set, t, q, qd);
  const double tv = 1e-12;
  EXPECT_TRUE(near(dr.value.phi, ref.phi, tv, tv)) << label << ": phi";
  EXPECT_TRUE(near(dr.value.phid, ref.phid, tv, tv)) << label << ": phid";
  EXPECT_TRUE(near(dr.value.gamma, ref.gamma, tv, tv * std::max(1.0, ref.gamma.cwiseAbs().maxCoeff())))
      << label << ": gamma";
  EXPECT_TRUE(near(dr.value.A, ref.A, tv, tv)) << label << ": A";
  worst.value = std::max({worst.value, test::rel_diff(dr.value.phi, ref.phi, 1.0),
                          test::rel_diff(dr.value.gamma, ref.gamma, 1.0), test::rel_diff(dr.value.A, ref.A, 1.0)});
  int compared = 0;
  for (int c = 0; c < 2 * n; ++c) {
    Eigen::VectorXd qp = q, qm = q, vp = qd, vm = qd;
    const bool is_q = c < n;
    const int j = is_q ? c : c - n;
    const double h = 1e-6 * (1.0 + std::fabs(is_q ? q[j] : qd[j]));
    (is_q ? qp : vp)[j] += h;
    (is_q ? qm : vm)[j] -= h;
    const Plain p = eval_double(model, set, t, qp, vp), m = eval_double(model, set, t, qm, vm);
    const Plain fd{(p.phi - m.phi) / (2 * h), (p.phid - m.phid) / (2 * h), (p.gamma - m.gamma) / (2 * h),
                   (p.A - m.A) / (2 * h)};
    const Plain& d = dr.deriv[c];
    const std::string where = label + ", d/d" + (is_q ? "q" : "qd") + "[" + std::to_string(j) + "]";
    EXPECT_TRUE(near(d.phi, fd.phi, 1e-7, floor_of(fd.phi))) << where << ": phi";
    EXPECT_TRUE(near(d.phid, fd.phid, 1e-7, floor_of(fd.phid))) << where << ": phid";
    EXPECT_TRUE(near(d.gamma, fd.gamma, 1e-7, floor_of(fd.gamma))) << where << ": gamma";
    EXPECT_TRUE(near(d.A, fd.A, 1e-7, floor_of(fd.A))) << where << ": A";
    for (const auto& [a, b] : {std::pair{&d.phi, &fd.phi}, {&d.phid, &fd.phid}, {&d.gamma, &fd.gamma}})
      worst.deriv = std::max(worst.deriv, test::rel_diff(*a, *b, 1.0));
    worst.deriv = std::max(worst.deriv, test::rel_diff(d.A, fd.A, 1.0));
    compared += 3 * set.rows() + static_cast<int>(d.A.size());
  }
  return compared;
}

// The random models of constraints_test with points tip, mid (on a link) and anchor (world).
using Case = test::RandomModelCase;
std::vector<Case> model_zoo(std::mt19937& rng, int dof) {
  test::ZooOptions o;
  o.dof_in_label = true;
  return test::model_zoo(rng, dof, o);
}

using test::all_kinds;
using test::random_unit;
using test::renamed;

/// (3) one expression constraint per order, with the functions of the language in it.
ConstraintSet expression_kinds(const Model& model) {
  const std::string j0 = model.joint_name[0], j1 = model.joint_name[model.nq - 1];
  ConstraintSet set;
  set.add(expression_constraint(
      model, "expr_position",
      "sin(x(tip))*cos(q(" + j0 + ")) + exp(0.3*y(mid)) + sqrt(1 + z(tip)^2) + pow(2 + cos(q(" + j1 +
          ")), 1.3) + atan2(y(tip), x(mid) + 4) + pow(1.5 + sin(x(mid)), 0.5 + 0.1*cos(z(tip))) + min(x(tip), y(mid)) "
          "+ abs(z(mid) - 7) + tan(0.2*q(" + j1 + ")) + log(3 + sin(t)) - a",
      false, {{"a", 2.0}}));
  set.add(expression_constraint(
      model, "expr_velocity",
      "vx(tip)*cos(x(mid)) + exp(0.2*qd(" + j0 + "))*sin(q(" + j1 + ")) + sqrt(2 + vy(tip)^2) + atan2(vz(mid), 2 + y(tip)^2) "
          "+ pow(1.2 + sin(t), 1.5)*qd(" + j1 + ") + tanh(vx(mid))*asinh(z(tip)) - 1",
      true));
  set.add(expression_constraint(
      model, "expr_acceleration",
      "ax(tip)*cos(q(" + j0 + ")) + exp(0.1*x(mid))*qdd(" + j1 + ") + sqrt(1 + vx(tip)^2)*az(mid) + atan2(y(tip), 3) "
          "+ pow(2 + sin(q(" + j1 + ")), 1.5)*vy(mid) + sin(t)*ay(tip)*qd(" + j0 + ")",
      ConstraintOrder::Acceleration));
  return set;
}

}  // namespace

TEST(ConstraintJacobian, EveryReadyMadeKindMatchesValuesAndFiniteDifferences) {
  std::mt19937 rng(2021);
  Worst worst;
  int compared = 0;
  for (int dof : {4, 7})
    for (const Case& c : model_zoo(rng, dof)) {
      const Model model = build_model(c.desc);
      const ConstraintSet set = all_kinds(model, rng);
      for (int trial = 0; trial < 2; ++trial) {
        const Eigen::VectorXd q = test::random_vector(rng, model.nq, 3.0);
        const Eigen::VectorXd qd = test::random_vector(rng, model.nq, 2.0);
        const double t = std::uniform_real_distribution<double>(0.0, 3.0)(rng);
        compared += check_state(model, set, t, q, qd, c.label + " trial " + std::to_string(trial), worst);
      }
    }
  EXPECT_GT(compared, 10000);
  std::printf("ready-made kinds: %d derivative entries, worst value rel diff %.2e, worst derivative rel diff %.2e\n",
              compared, worst.value, worst.deriv);
}

TEST(ConstraintJacobian, ExpressionConstraintsOfEveryOrder) {
  std::mt19937 rng(77);
  Worst worst;
  int compared = 0;
  for (int dof : {3, 6})
    for (const Case& c : model_zoo(rng, dof)) {
      const Model model = build_model(c.desc);
      const ConstraintSet set = expression_kinds(model);
      ASSERT_EQ(set.rows(), 3);
      for (int trial = 0; trial < 2; ++trial) {
        const Eigen::VectorXd q = test::random_vector(rng, model.nq, 2.0);
        const Eigen::VectorXd qd = test::random_vector(rng, model.nq, 1.5);
        const double t = std::uniform_real_distribution<double>(0.0, 3.0)(rng);
        compared += check_state(model, set, t, q, qd, c.label + " trial " + std::to_string(trial), worst);
      }
    }
  std::printf("expression constraints: %d derivative entries, worst value rel diff %.2e, worst derivative rel "
              "diff %.2e\n", compared, worst.value, worst.deriv);
}

TEST(ConstraintJacobian, ExpressionDualTapeMatchesTheDoubleTape) {
  // Value, gradient and Hessian of the dual tape equal the double ones (value parts), and the
  // derivative parts equal the next derivatives (gradient → Hessian) of the double tape.
  const std::vector<std::string> vars = {"x", "y", "z"};
  for (const std::string text : {"x^2 + 3*y*z - 1", "sin(x)*exp(y) + sqrt(1 + z^2) + atan2(y, x + 3)",
                                 "pow(1.5 + cos(x), 0.5 + 0.1*y) + abs(z) + if(x < y, x*y, z^3)"}) {
    const Expression e(text, vars, {}, 2);
    const double x0[3] = {0.4, -0.7, 1.3};
    double v = 0, g[3], H[9];
    e.evaluate(x0, v, g, H);
    JS xs[3], vd, gd[3], Hd[9];
    for (int k = 0; k < 3; ++k) xs[k] = JS::variable(x0[k], k);
    ExpressionDualWorkspace ws(e);
    e.evaluate(xs, vd, gd, Hd, ws);
    EXPECT_NEAR(vd.v, v, 1e-14 * std::max(1.0, std::fabs(v))) << text;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(vd.d[k], g[k], 1e-13 * std::max(1.0, std::fabs(g[k]))) << text;
      EXPECT_NEAR(gd[k].v, g[k], 1e-14 * std::max(1.0, std::fabs(g[k]))) << text;
      for (int l = 0; l < 3; ++l) EXPECT_NEAR(gd[k].d[l], H[3 * k + l], 1e-12 * std::max(1.0, std::fabs(H[3 * k + l])))
          << text << " d grad_" << k << " / d x_" << l;
    }
    // The Hessian's derivative parts against central differences of the double Hessian.
    for (int l = 0; l < 3; ++l) {
      double xp[3] = {x0[0], x0[1], x0[2]}, xm[3] = {x0[0], x0[1], x0[2]}, Hp[9], Hm[9], gp[3], vp;
      const double h = 1e-6;
      xp[l] += h;
      xm[l] -= h;
      e.evaluate(xp, vp, gp, Hp);
      e.evaluate(xm, vp, gp, Hm);
      for (int k = 0; k < 9; ++k) {
        const double fd = (Hp[k] - Hm[k]) / (2 * h);
        EXPECT_NEAR(Hd[k].d[l], fd, 1e-7 * std::max(1.0, std::fabs(fd))) << text << " dH_" << k << "/dx_" << l;
      }
    }
    // The order checks of the double evaluate apply.
    const Expression e0(text, vars, {}, 0);
    test::expect_error_mentioning([&] { e0.evaluate(xs, vd, gd, nullptr, ws); }, {"gradient requested"});
  }
}

TEST(ConstraintJacobian, DistanceKind) {
  // A planar 2R arm with a base point B and the tip E; |E − B| follows d(t).
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
  - {name: reach, kind: distance, points: [B, E], length: d0 + dd*(1 - cos(2*pi*t/T))/2}
partition: {independent: [q1, q3]}
initial: {q: [0, 1.0, 0.1], consistency: project}
integrator: {method: rk4, step: 1e-3, t1: 2}
)";
  const auto problem = io::parse_problem(yaml, "distance.yaml");
  std::mt19937 rng(5);
  Worst worst;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::VectorXd q = test::random_vector(rng, 3, 2.0), qd = test::random_vector(rng, 3, 1.5);
    check_state(problem->model, problem->constraints, 0.2 + 0.3 * trial, q, qd, "distance trial " + std::to_string(trial),
                worst);
  }
  std::printf("distance: worst value rel diff %.2e, worst derivative rel diff %.2e\n", worst.value, worst.deriv);
}

TEST(ConstraintJacobian, ExampleScenarios) {
  for (const std::string file : {"paper/paper.yaml", "four_bar/four_bar.yaml", "unicycle/unicycle.yaml",
                                 "planar_2r_circle/planar_2r_circle.yaml", "waiter_tray/waiter_tray.yaml",
                                 "urdf_arm_line/urdf_arm_line.yaml"}) {
    const auto problem = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/examples/" + file);
    std::mt19937 rng(11);
    Worst worst;
    int compared = 0;
    // at the scenario's initial state and at perturbed ones
    for (int trial = 0; trial < 3; ++trial) {
      const int n = problem->model.nv;
      const Eigen::VectorXd q = problem->q0 + (trial ? test::random_vector(rng, n, 0.3) : Eigen::VectorXd::Zero(n));
      const Eigen::VectorXd qd = problem->qd0 + test::random_vector(rng, n, 0.5);
      compared += check_state(problem->model, problem->constraints, 0.37 * trial, q, qd,
                              file + " trial " + std::to_string(trial), worst);
    }
    std::printf("%s: %d rows, %d derivative entries, worst value rel diff %.2e, worst derivative rel diff %.2e\n",
                file.c_str(), problem->constraints.rows(), compared, worst.value, worst.deriv);
  }
}

namespace {
/// A kind without evaluate_dual (the default).
class NoDual final : public Constraint {
 public:
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return false; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    phi[0] = in.q[0];
    phid[0] = in.qd[0];
    A.setZero();
    A(0, 0) = 1;
    gamma[0] = 0;
  }
  std::string describe() const override { return "a test kind"; }
};
}  // namespace

TEST(ConstraintJacobian, KindWithoutDualThrowsAClearError) {
  std::mt19937 rng(3);
  const Model model = build_model(test::random_chain(rng));
  ConstraintSet set;
  set.add(joint_trajectory(model, model.joint_name[0], polynomial({0.1, 0.2})));
  auto c = std::make_shared<NoDual>();
  c->name = "legacy";
  set.add(c);
  ConstraintEvalDual ev(model, set);
  std::vector<JS> q(model.nv, JS(0.1)), qd(model.nv, JS(0.2));
  test::expect_error_mentioning([&] { evaluate_constraints_dual(model, set, ev, 0.0, q.data(), qd.data()); },
                                {"constraint 'legacy' (a test kind) has no exact derivatives"});
  // A workspace of another set or model is refused.
  ConstraintSet other;
  other.add(joint_trajectory(model, model.joint_name[0], polynomial({0.1, 0.2})));
  test::expect_error_mentioning([&] { evaluate_constraints_dual(model, other, ev, 0.0, q.data(), qd.data()); },
                                {"ConstraintEvalDual was built for another model or constraint set"});
}
