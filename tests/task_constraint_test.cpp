// Expression constraints against the hand-written ready-made kinds they replace.
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "test_support.hpp"

#include <cmath>
#include <numbers>
#include <thread>

using namespace refdyn;
using refdyn::test::near;

namespace {

struct Eval {
  Eigen::VectorXd phi, phid, gamma;
  Eigen::MatrixXd A;
};

Eval eval(const Model& m, ConstraintPtr c, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  ConstraintSet set;
  set.add(std::move(c));
  Data data(m);
  ConstraintEval ev(m, set);
  evaluate_constraints(m, data, set, ev, t, q, qd);
  return {ev.phi, ev.phid, ev.gamma, ev.A};
}

void expect_same(const Eval& a, const Eval& b) {
  EXPECT_TRUE(near(a.phi, b.phi, 1e-12, 1e-14));
  EXPECT_TRUE(near(a.phid, b.phid, 1e-12, 1e-14));
  EXPECT_TRUE(near(a.A, b.A, 1e-12, 1e-14));
  EXPECT_TRUE(near(a.gamma, b.gamma, 1e-12, 1e-14));
}

}  // namespace

TEST(ExpressionConstraint, MatchesHandWrittenKindsOnRandomStates) {
  std::mt19937 rng(7);
  for (int rep = 0; rep < 10; ++rep) {
    test::RandomChainOptions o;
    o.dof = 2 + rep % 6;
    const Model m = build_model(test::random_chain(rng, o));
    const Eigen::VectorXd q = test::random_vector(rng, m.nq, 2.0), qd = test::random_vector(rng, m.nq, 1.5);
    const double t = 0.37 * rep;
    // Ellipse on the tip.
    expect_same(eval(m, point_on_surface(m, "tip", elliptic_cylinder(0.7, 0.3, 0.1, -0.2)), t, q, qd),
                eval(m, expression_constraint(m, "e", "((x(tip) - cx)/a)^2 + ((y(tip) - cy)/b)^2 - 1", false,
                                              {{"a", 0.7}, {"b", 0.3}, {"cx", 0.1}, {"cy", -0.2}}),
                     t, q, qd));
    // A coordinate following a time function.
    expect_same(eval(m, point_coordinate(m, "tip", 2, raised_cosine(0.3, 0.1, 2.0)), t, q, qd),
                eval(m, expression_constraint(m, "h", "z(tip) - (z0 + dz*(1 - cos(2*pi*t/T))/2)", false,
                                              {{"z0", 0.3}, {"dz", 0.1}, {"T", 2.0}}),
                     t, q, qd));
    // Prescribed joint motion.
    expect_same(eval(m, joint_trajectory(m, m.joint_name[0], sinusoid(0.5, 2.0, 0.1)), t, q, qd),
                eval(m, expression_constraint(m, "j", "q(" + m.joint_name[0] + ") - 0.5*sin(2*t + 0.1)"), t, q, qd));
    // First order: speed along a fixed direction.
    const Vec3 u = Vec3(0.3, -0.5, 0.8).normalized();
    expect_same(eval(m, point_speed(m, "tip", u, constant(0.25)), t, q, qd),
                eval(m, expression_constraint(m, "s", "ux*vx(tip) + uy*vy(tip) + uz*vz(tip) - 0.25", true,
                                              {{"ux", u.x()}, {"uy", u.y()}, {"uz", u.z()}}),
                     t, q, qd));
  }
}

TEST(ExpressionConstraint, FirstOrderGammaByFiniteDifferences) {
  // c = qd(q1)·x(tip) − sin(t)·qd(q2)·q(q1): ċ along a random q̈ equals A q̈ + γ.
  std::mt19937 rng(11);
  test::RandomChainOptions o;
  o.dof = 4;
  const Model m = build_model(test::random_chain(rng, o));
  auto c = expression_constraint(m, "c", "qd(q1)*x(tip) - sin(t)*qd(q2)*q(q1)", true);
  const Eigen::VectorXd q = test::random_vector(rng, 4, 1.0), qd = test::random_vector(rng, 4, 1.0),
                        qdd = test::random_vector(rng, 4, 1.0);
  const double t = 0.4, h = 1e-6;
  const Eval e0 = eval(m, c, t, q, qd);
  auto at = [&](double s) {
    return eval(m, c, t + s, q + qd * s + 0.5 * qdd * s * s, qd + qdd * s).phi[0];
  };
  const double cdot_fd = (at(h) - at(-h)) / (2 * h);
  EXPECT_NEAR((e0.A * qdd)(0) + e0.gamma[0], cdot_fd, 1e-7);
  EXPECT_TRUE(c->first_order());
  EXPECT_TRUE(c->rheonomic());
}

TEST(ExpressionConstraint, ClearErrors) {
  const Model m = models::paper_manipulator();
  try {
    expression_constraint(m, "bad", "x(F)^2 - 1");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string s = e.what();
    EXPECT_NE(s.find("constraint 'bad'"), std::string::npos) << s;
    EXPECT_NE(s.find("x(F)"), std::string::npos) << s;
  }
  try {
    expression_constraint(m, "vel", "vx(E) - 1");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("first-order"), std::string::npos) << e.what();
  }
  EXPECT_THROW(expression_constraint(m, "syntax", "(x(E) - 1"), Error);
  EXPECT_THROW(expression_constraint(m, "", "x(E)"), Error);
  EXPECT_THROW(expression_time_function("sin(2*pi*t/T"), Error);
}

TEST(ExpressionConstraint, PaperRunIdenticalToHandWritten) {
  Eigen::VectorXd finals[2];
  for (int k = 0; k < 2; ++k) {
    models::PaperExampleParams p;
    p.expression_constraints = k == 1;
    models::PaperExample ex(p);
    ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
    Eigen::VectorXd x = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3));
    IntegratorOptions io = ex.integrator();
    io.t1 = 1.0;
    const auto s = integrate([&](double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) { rd.derivative(t, xx, dx); },
                             x, io);
    ASSERT_TRUE(s.ok()) << s.message;
    finals[k] = x;
  }
  EXPECT_TRUE(near(finals[0], finals[1], 1e-12, 1e-14));
  EXPECT_NEAR(finals[1][0], 0.30556157, 1e-7);
  EXPECT_NEAR(finals[1][2], 0.51502438, 1e-7);
}

TEST(ExpressionTimeFunction, DerivativesExact) {
  auto f = expression_time_function("A*sin(w*t) + t^3", {{"A", 2.0}, {"w", 3.0}});
  const double t = 0.7;
  const TimeValue v = f->eval(t);
  EXPECT_NEAR(v.f, 2 * std::sin(2.1) + t * t * t, 1e-14);
  EXPECT_NEAR(v.df, 6 * std::cos(2.1) + 3 * t * t, 1e-13);
  EXPECT_NEAR(v.ddf, -18 * std::sin(2.1) + 6 * t, 1e-12);
}

// Constraint objects hold no mutable state: one set evaluated from two threads at once (each
// with its own Data and ConstraintEval) gives exactly the serial results.
TEST(ExpressionConstraint, OneSetEvaluatedFromTwoThreadsAtOnce) {
  const Model m = models::paper_manipulator();
  ConstraintSet set;
  set.add(expression_constraint(m, "ellipse", "(x(E)/a)^2 + (y(E)/b)^2 - 1 + 0.1*sin(t)*z(E)", false,
                                {{"a", 0.35}, {"b", 0.25}}));
  set.add(expression_constraint(m, "speed", "vx(E)*x(E) + vy(E)*y(E) - 0.1*cos(t)", true));
  std::mt19937 rng(11);
  const int K = 400;
  std::vector<Eigen::VectorXd> q, qd;
  for (int k = 0; k < K; ++k) q.push_back(test::random_vector(rng, 3)), qd.push_back(test::random_vector(rng, 3));
  auto run = [&](int first, int last, std::vector<Eigen::MatrixXd>& out) {
    Data data(m);
    ConstraintEval ev(m, set);
    for (int rep = 0; rep < 20; ++rep)
      for (int k = first; k < last; ++k) {
        evaluate_constraints(m, data, set, ev, 0.01 * k, q[k], qd[k]);
        Eigen::MatrixXd r(2, 6);
        r << ev.A, ev.phi, ev.phid, ev.gamma;
        out[k] = r;
      }
  };
  std::vector<Eigen::MatrixXd> serial(K), parallel(K);
  run(0, K, serial);
  std::thread a([&] { run(0, K / 2, parallel); });
  std::thread b([&] { run(K / 2, K, parallel); });
  a.join();
  b.join();
  for (int k = 0; k < K; ++k) ASSERT_EQ(serial[k], parallel[k]) << k;
}

// A parameter that cancels a variable (k = 0) leaves a valid constraint; one that leaves no
// state at all is reported as such (it once gave "unknown identifier").
TEST(ExpressionConstraint, ParameterThatCancelsAVariable) {
  const Model m = models::paper_manipulator();
  std::mt19937 rng(3);
  const Eigen::VectorXd q = test::random_vector(rng, 3), qd = test::random_vector(rng, 3);
  const Eval with_zero = eval(m, expression_constraint(m, "c", "x(E) - 1 + k*q(psi1) + k*t", false, {{"k", 0.0}}), 0.4, q, qd);
  const Eval plain = eval(m, expression_constraint(m, "c", "x(E) - 1", false), 0.4, q, qd);
  expect_same(with_zero, plain);
  EXPECT_FALSE(expression_constraint(m, "c", "x(E) - 1 + k*t", false, {{"k", 0.0}})->rheonomic());
  test::expect_error_mentioning([&] { expression_constraint(m, "c", "k*q(psi1) + t - 1", false, {{"k", 0.0}}); },
                                {"constraint 'c'", "does not depend on the state"});
}
