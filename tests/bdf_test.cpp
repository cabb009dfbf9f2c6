// integrate_bdf (CVODES BDF, exact Jacobian) against closed-form solutions of stiff systems and a
// classic benchmark; its options and failures.
#include "refdyn/simulate/bdf.hpp"
#include "refdyn/common/error.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace refdyn {
namespace {

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
  BdfOptions o;
  o.rtol = 1e-9;
  o.atol = 1e-12;
  const std::vector<double> outputs = {0.001, 0.5, 1.0, 2.0};
  const BdfResult r = integrate_bdf(f, J, 0.0, x0, outputs, o);
  ASSERT_TRUE(r.ok) << r.message;
  ASSERT_EQ(r.x.size(), 5u);
  const Eigen::Vector2d c = V.inverse() * x0;
  for (size_t k = 1; k < r.t.size(); ++k) {
    const double t = r.t[k];
    const Eigen::Vector2d exact = V * Eigen::Vector2d(c[0] * std::exp(-t), c[1] * std::exp(-1e5 * t));
    EXPECT_NEAR(r.x[k][0], exact[0], 1e-7 * std::abs(exact[0]) + 1e-10) << "t = " << t;
    EXPECT_NEAR(r.x[k][1], exact[1], 1e-7 * std::abs(exact[1]) + 1e-10) << "t = " << t;
  }
  // Explicit RK4 is stable only for h < 2.79/1e5: 2 s take it more than 71,000 steps.
  EXPECT_LT(r.counters.steps, 2000) << r.counters.steps;
  EXPECT_GT(r.counters.jacobian_evaluations, 0);
  EXPECT_GE(r.counters.rhs_evaluations, r.counters.steps);
  EXPECT_GE(r.counters.last_order, 1);
  EXPECT_LE(r.counters.last_order, 5);
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
  BdfOptions o;
  o.rtol = 1e-8;
  o.atol = 1e-14;
  const BdfResult r = integrate_bdf(f, J, 0.0, Eigen::Vector3d(1, 0, 0), {0.4, 4, 40}, o);
  ASSERT_TRUE(r.ok) << r.message;
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
  const BdfResult a = integrate_bdf(f, exact, 0, x0, {1.0});
  const BdfResult b = integrate_bdf(f, wrong, 0, x0, {1.0});
  ASSERT_TRUE(a.ok && b.ok) << a.message << b.message;
  EXPECT_NEAR(a.x.back()[0], 1.0, 1e-6);
  EXPECT_NEAR(b.x.back()[0], 1.0, 1e-6);
  EXPECT_GT(b.counters.newton_iterations, a.counters.newton_iterations);
}

TEST(Bdf, InvalidOptionsAreErrors) {
  auto f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = -x; };
  auto J = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -Eigen::MatrixXd::Identity(x.size(), x.size()); };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Ones(1);
  BdfOptions o;
  o.rtol = 0;
  EXPECT_THROW(integrate_bdf(f, J, 0, x0, {1}, o), Error);
  o = {};
  o.atol = std::nan("");
  EXPECT_THROW(integrate_bdf(f, J, 0, x0, {1}, o), Error);
  o = {};
  o.max_order = 6;
  EXPECT_THROW(integrate_bdf(f, J, 0, x0, {1}, o), Error);
  o = {};
  EXPECT_THROW(integrate_bdf(f, J, 0, x0, {1, 0.5}, o), Error);  // not increasing
  EXPECT_THROW(integrate_bdf(f, BdfJacobian(), 0, x0, {1}, o), Error);  // no Jacobian: no finite differences
}

TEST(Bdf, FailuresAreReportedWithTimeAndReason) {
  auto J = [](double, const Eigen::VectorXd& x, Eigen::MatrixXd& j) { j = -Eigen::MatrixXd::Identity(x.size(), x.size()); };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Ones(1);
  auto throws = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    if (t > 0.5) throw Error("the model broke");
    dx = -x;
  };
  BdfResult r = integrate_bdf(throws, J, 0, x0, {0.25, 1.0});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.t.size(), 2u);  // t0 and 0.25
  EXPECT_NE(r.message.find("the model broke"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("at t = 0."), std::string::npos) << r.message;
  auto f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = -x; };
  BdfOptions o;
  o.max_steps = 3;
  r = integrate_bdf(f, J, 0, x0, {100.0}, o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("max_steps"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace refdyn
