// integrate() with method bdf (CVODES BDF, exact Jacobian) against closed-form solutions of stiff
// systems and a classic benchmark; its options, counters and failures.
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace refdyn {
namespace {

/// The states at the observer's samples.
struct Outcome {
  IntegrationSummary summary;
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x;
};
Outcome run_bdf(const OdeRhs& f, const OdeJacobian& J, const Eigen::VectorXd& x0, IntegratorOptions o) {
  o.method = IntegratorMethod::BDF;
  Outcome r;
  Eigen::VectorXd x = x0;
  r.summary = integrate(f, x, o, [&](double t, const Eigen::VectorXd& xx) {
    r.t.push_back(t);
    r.x.push_back(xx);
    return true;
  }, J);
  return r;
}
IntegratorOptions span(double t1, double every, double rtol = 1e-6, double atol = 1e-9) {
  IntegratorOptions o;
  o.t1 = t1;
  o.step = every;
  o.rtol = rtol;
  o.atol = atol;
  o.min_step = 1e-14;
  return o;
}

// x' = A x with eigenvalues −1 and −1e5 (stiffness ratio 1e5): x(t) = V e^{Λt} V⁻¹ x0.
TEST(Bdf, StiffLinearSystemMatchesTheExactSolution) {
  Eigen::Matrix2d V, L = Eigen::Matrix2d::Zero();
  V << 1, 1, 1, -2;
  L(0, 0) = -1;
  L(1, 1) = -1e5;
  const Eigen::Matrix2d A = V * L * V.inverse();
  const Eigen::Vector2d x0(1, 0.5);
  auto f = [&](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = A * x; };
  auto J = [&](double, const Eigen::VectorXd&, Eigen::MatrixXd& j) { j = A; };
  const Outcome r = run_bdf(f, J, x0, span(2.0, 0.25, 1e-9, 1e-12));
  ASSERT_TRUE(r.summary.ok()) << r.summary.message;
  ASSERT_EQ(r.x.size(), 9u);  // t0 and every 0.25 s
  EXPECT_EQ(r.t.back(), 2.0);
  const Eigen::Vector2d c = V.inverse() * x0;
  for (size_t k = 1; k < r.t.size(); ++k) {
    const double t = r.t[k];
    const Eigen::Vector2d exact = V * Eigen::Vector2d(c[0] * std::exp(-t), c[1] * std::exp(-1e5 * t));
    EXPECT_NEAR(r.x[k][0], exact[0], 1e-7 * std::abs(exact[0]) + 1e-10) << "t = " << t;
    EXPECT_NEAR(r.x[k][1], exact[1], 1e-7 * std::abs(exact[1]) + 1e-10) << "t = " << t;
  }
  // Explicit RK4 is stable only for h < 2.79/1e5: 2 s take it more than 71,000 steps.
  const IntegrationSummary& s = r.summary;
  EXPECT_LT(s.steps, 2000) << s.steps;
  EXPECT_GT(s.jacobian_evaluations, 0);
  EXPECT_GE(s.rhs_evaluations, s.steps);
  EXPECT_GE(s.newton_iterations, s.steps);
  EXPECT_EQ(s.rejected_steps, s.newton_failures + s.error_test_failures);
  EXPECT_EQ(s.t_end, 2.0);
}

// Robertson's chemical kinetics (Hairer & Wanner, Solving ODEs II, §IV.1): y1 + y2 + y3 = 1 is
// kept, and y(40) has the published values 0.7158271, 9.185535e-6, 0.2841637.
TEST(Bdf, RobertsonKineticsKeepsMassAndMatchesReference) {
  auto f = [](double, const Eigen::VectorXd& y, Eigen::VectorXd& d) {
    d.resize(3);
    d[0] = -0.04 * y[0] + 1e4 * y[1] * y[2];
    d[2] = 3e7 * y[1] * y[1];
    d[1] = -d[0] - d[2];
  };
  auto J = [](double, const Eigen::VectorXd& y, Eigen::MatrixXd& j) {
    j.resize(3, 3);
    j << -0.04, 1e4 * y[2], 1e4 * y[1],                                   //
        0.04, -1e4 * y[2] - 6e7 * y[1], -1e4 * y[1],                      //
        0, 6e7 * y[1], 0;
  };
  const Outcome r = run_bdf(f, J, Eigen::Vector3d(1, 0, 0), span(40, 4, 1e-8, 1e-14));
  ASSERT_TRUE(r.summary.ok()) << r.summary.message;
  for (const auto& y : r.x) EXPECT_NEAR(y.sum(), 1.0, 1e-9);
  EXPECT_NEAR(r.x.back()[0], 0.7158271, 2e-7);
  EXPECT_NEAR(r.x.back()[1], 9.185535e-6, 2e-11);
  EXPECT_NEAR(r.x.back()[2], 0.2841637, 2e-7);
}

// The Jacobian is the caller's exact one: a wrong Jacobian slows the Newton iteration (more
// iterations and failures) but the error control keeps the answer right.
TEST(Bdf, AWrongJacobianCostsIterationsNotAccuracy) {
  auto f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = -1e4 * (x.array() - 1).matrix(); };
  auto exact = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -1e4 * Eigen::MatrixXd::Identity(x.size(), x.size()); };
  auto wrong = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -1e3 * Eigen::MatrixXd::Identity(x.size(), x.size()); };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(2);
  const Outcome a = run_bdf(f, exact, x0, span(1, 0.5));
  const Outcome b = run_bdf(f, wrong, x0, span(1, 0.5));
  ASSERT_TRUE(a.summary.ok() && b.summary.ok()) << a.summary.message << b.summary.message;
  EXPECT_NEAR(a.x.back()[0], 1.0, 1e-6);
  EXPECT_NEAR(b.x.back()[0], 1.0, 1e-6);
  EXPECT_GT(b.summary.newton_iterations, a.summary.newton_iterations);
}

TEST(Bdf, InvalidOptionsAreErrors) {
  auto f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = -x; };
  auto J = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -Eigen::MatrixXd::Identity(x.size(), x.size()); };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Ones(1);
  IntegratorOptions o = span(1, 0.1);
  o.rtol = 0;
  test::expect_error_mentioning([&] { run_bdf(f, J, x0, o); }, {"rtol"});
  o = span(1, 0.1);
  o.atol = std::nan("");
  test::expect_error_mentioning([&] { run_bdf(f, J, x0, o); }, {"atol"});
  o = span(1, 0.1);
  o.max_order = 6;
  test::expect_error_mentioning([&] { run_bdf(f, J, x0, o); }, {"max_order", "1 to 5"});
  o.max_order = 0;
  test::expect_error_mentioning([&] { run_bdf(f, J, x0, o); }, {"max_order"});
  // No Jacobian: refused (no finite differences).
  test::expect_error_mentioning([&] { run_bdf(f, OdeJacobian(), x0, span(1, 0.1)); }, {"Jacobian"});
  // A Jacobian of the wrong size is an Error, not a crash.
  auto bad = [](double, const Eigen::VectorXd&, Eigen::MatrixXd& j) { j = Eigen::MatrixXd::Identity(2, 2); };
  test::expect_error_mentioning([&] { run_bdf(f, bad, x0, span(1, 0.1)); }, {"Jacobian has size 2x2", "expected 1x1"});
}

TEST(Bdf, FailuresAreReportedWithTimeAndReason) {
  auto J = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -Eigen::MatrixXd::Identity(x.size(), x.size()); };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Ones(1);
  // A NumericalFailure of the right-hand side (a singular partition) is the run's status.
  auto singular = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    if (t > 0.5) throw NumericalFailure(t, "the model broke");
    dx = -x;
  };
  Outcome r = run_bdf(singular, J, x0, span(1, 0.25));
  EXPECT_EQ(r.summary.status, IntegrationStatus::NumericalFailure);
  // BDF steps past an output time before interpolating back to it, so the failure may come
  // while it is reaching 0.5: the samples are those before the failure, t0 and 0.25 at least.
  EXPECT_GE(r.t.size(), 2u);
  EXPECT_LE(r.summary.t_end, 0.5);
  EXPECT_EQ(r.summary.t_end, r.t.back());
  EXPECT_NE(r.summary.message.find("the model broke"), std::string::npos) << r.summary.message;
  // Any other exception is the caller's and is rethrown after SUNDIALS is cleaned up.
  auto throws = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    if (t > 0.5) throw Error("bad input");
    dx = -x;
  };
  test::expect_error_mentioning([&] { run_bdf(throws, J, x0, span(1, 0.25)); }, {"bad input"});
  // The step budget is the whole run's.
  auto f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = -x; };
  IntegratorOptions o = span(100, 1);
  o.max_steps = 30;
  r = run_bdf(f, J, x0, o);
  EXPECT_EQ(r.summary.status, IntegrationStatus::MaxSteps);
  EXPECT_NE(r.summary.message.find("max_steps = 30"), std::string::npos) << r.summary.message;
  EXPECT_LE(r.summary.steps, 31);
  // A right-hand side that turns NaN and stays so: non-finite, with the time.
  auto nan = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    dx = -x;
    if (t > 0.3) dx[0] = std::nan("");
  };
  r = run_bdf(nan, J, x0, span(1, 0.1));
  EXPECT_EQ(r.summary.status, IntegrationStatus::NonFinite);
  EXPECT_EQ(r.summary.message.rfind("at t = ", 0), 0u) << r.summary.message;
  EXPECT_NEAR(std::stod(r.summary.message.substr(7)), 0.3, 1e-6) << r.summary.message;  // where f turned NaN
  EXPECT_TRUE(r.x.back().allFinite());
}

}  // namespace
}  // namespace refdyn
