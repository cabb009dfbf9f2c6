// Integrators: RK4's order of accuracy, Dormand–Prince's tolerance-level accuracy and dense
// output at the requested times, summary bookkeeping, and how failures are reported (NaN,
// NumericalFailure from the right-hand side, finite-time blow-up, observer stop, bad options).
#include "refdyn/common/error.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <cmath>
#include <limits>
#include <numbers>

using namespace refdyn;
using refdyn::test::expect_error_mentioning;
using refdyn::test::near;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Sample {
  double t;
  Eigen::VectorXd x;
};

/// ẋ = λx.
OdeRhs exponential(double lambda, long* count = nullptr) {
  return [lambda, count](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    if (count) ++*count;
    dx = lambda * x;
  };
}

/// Harmonic oscillator ẍ = −ω² x as [x, ẋ].
OdeRhs oscillator(double w) {
  return [w](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    dx[0] = x[1];
    dx[1] = -w * w * x[0];
  };
}

double rk4_error_exp(double h) {
  Eigen::VectorXd x(1);
  x[0] = 1.0;
  IntegratorOptions o;
  o.t1 = 1.0;
  o.step = h;
  auto s = integrate(exponential(-2.0), x, o);
  EXPECT_TRUE(s.ok()) << s.message;
  return std::abs(x[0] - std::exp(-2.0));
}

double rk4_error_oscillator(double h) {
  const double w = 3.0;
  Eigen::VectorXd x(2);
  x << 1.0, 0.0;
  IntegratorOptions o;
  o.t1 = 2.0;
  o.step = h;
  auto s = integrate(oscillator(w), x, o);
  EXPECT_TRUE(s.ok()) << s.message;
  Eigen::Vector2d exact(std::cos(w * 2.0), -w * std::sin(w * 2.0));
  return (x - exact).cwiseAbs().maxCoeff();
}

}  // namespace

TEST(Rk4, FourthOrderOnExponentialDecay) {
  const double e1 = rk4_error_exp(0.1), e2 = rk4_error_exp(0.05), e3 = rk4_error_exp(0.025);
  // Leading error term (λh)⁵/120 per step → global ∝ h⁴: ratio 16 (±10 %).
  EXPECT_NEAR(e1 / e2, 16.0, 1.6) << e1 << " " << e2;
  EXPECT_NEAR(e2 / e3, 16.0, 1.6) << e2 << " " << e3;
  EXPECT_LT(e3, 1e-7);
}

TEST(Rk4, FourthOrderOnHarmonicOscillator) {
  const double e1 = rk4_error_oscillator(0.02), e2 = rk4_error_oscillator(0.01), e3 = rk4_error_oscillator(0.005);
  EXPECT_NEAR(e1 / e2, 16.0, 1.6) << e1 << " " << e2;
  EXPECT_NEAR(e2 / e3, 16.0, 1.6) << e2 << " " << e3;
  EXPECT_LT(e3, 1e-8);
}

TEST(Rk4, SingleStepIsTheClassicalAmplificationFactor) {
  const double lambda = -1.7, h = 0.3, z = lambda * h;
  Eigen::VectorXd x(1);
  x[0] = 2.0;
  Rk4Workspace ws(1);
  rk4_step(exponential(lambda), 0.0, h, x, ws);
  EXPECT_NEAR(x[0], 2.0 * (1 + z + z * z / 2 + z * z * z / 6 + z * z * z * z / 24), 1e-15);
}

TEST(Rk4, LandsExactlyOnT1AndCountsStepsAndEvaluations) {
  long count = 0;
  Eigen::VectorXd x(1);
  x[0] = 1.0;
  IntegratorOptions o;
  o.t0 = 0.5;
  o.t1 = 1.5;
  o.step = 0.3;  // 1/0.3 is not an integer: 4 steps of 0.25
  std::vector<double> times;
  auto s = integrate(exponential(-1.0, &count), x, o, [&](double t, const Eigen::VectorXd&) {
    times.push_back(t);
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.message;
  EXPECT_EQ(s.steps, 4);
  EXPECT_EQ(s.rhs_evaluations, 16);
  EXPECT_EQ(count, 16);
  EXPECT_EQ(s.t_end, 1.5);
  EXPECT_EQ(times, (std::vector<double>{0.5, 0.75, 1.0, 1.25, 1.5}));
  EXPECT_TRUE(s.message.empty());
  EXPECT_GE(s.wall_time, 0.0);

  // Output interval: every 10th step of h = 0.01.
  times.clear();
  x[0] = 1.0;
  o.t0 = 0.0;
  o.t1 = 1.0;
  o.step = 0.01;
  o.output_interval = 0.1;
  s = integrate(exponential(-1.0), x, o, [&](double t, const Eigen::VectorXd& xx) {
    times.push_back(t);
    EXPECT_NEAR(xx[0], std::exp(-t), 1e-9) << t;
    return true;
  });
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(times.size(), 11u);
  for (int k = 0; k <= 10; ++k) EXPECT_NEAR(times[k], 0.1 * k, 1e-14);
  EXPECT_EQ(times.back(), 1.0);
}

TEST(DormandPrince, ReachesToleranceLevelAccuracyWithDenseOutputAtRequestedTimes) {
  for (double rtol : {1e-6, 1e-8, 1e-11}) {
    long count = 0;
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = IntegratorMethod::DormandPrince45;
    o.t0 = 0.2;
    o.t1 = 3.25;  // not a multiple of the output interval: last sample at t1
    o.step = 0.01;
    o.output_interval = 0.1;
    o.rtol = rtol;
    o.atol = 1e-14;
    std::vector<Sample> samples;
    auto s = integrate(exponential(-1.3, &count), x, o, [&](double t, const Eigen::VectorXd& xx) {
      samples.push_back({t, xx});
      return true;
    });
    ASSERT_TRUE(s.ok()) << s.message;
    EXPECT_EQ(s.t_end, 3.25);
    EXPECT_EQ(s.rhs_evaluations, count);
    EXPECT_GT(s.steps, 0);
    EXPECT_GE(s.rejected_steps, 0);
    EXPECT_LT(s.steps, 2000);
    // Samples at t0 + k·Δ exactly (k = 0 … 30), then t1.
    ASSERT_EQ(samples.size(), 32u) << "rtol " << rtol;
    for (int k = 0; k <= 30; ++k) EXPECT_EQ(samples[k].t, o.t0 + k * 0.1) << k;
    EXPECT_EQ(samples.back().t, 3.25);
    double worst = 0;
    for (const Sample& sm : samples) {
      const double exact = std::exp(-1.3 * (sm.t - 0.2));
      worst = std::max(worst, std::abs(sm.x[0] - exact) / exact);
    }
    // Global relative error of a few tolerances (the solution decays: errors accumulate
    // relative to the current value), and not absurdly better than asked.
    EXPECT_LT(worst, 20 * rtol) << "rtol " << rtol;
    EXPECT_NEAR(x[0], std::exp(-1.3 * 3.05), 20 * rtol * std::exp(-1.3 * 3.05));
    std::cout << "[ dopri ] rtol " << rtol << ": worst relative error " << worst << ", steps " << s.steps
              << ", rejected " << s.rejected_steps << ", rhs " << s.rhs_evaluations << "\n";
  }
}

TEST(DormandPrince, OscillatorDenseOutputAgreesWithTheExactSolution) {
  const double w = 5.0;
  Eigen::VectorXd x(2);
  x << 1.0, 0.0;
  IntegratorOptions o;
  o.method = IntegratorMethod::DormandPrince45;
  o.t1 = 4.0;
  o.step = 1e-3;
  o.output_interval = 0.01;
  o.rtol = 1e-10;
  o.atol = 1e-12;
  double worst = 0;
  int n = 0;
  auto s = integrate(oscillator(w), x, o, [&](double t, const Eigen::VectorXd& xx) {
    worst = std::max(worst, std::abs(xx[0] - std::cos(w * t)));
    worst = std::max(worst, std::abs(xx[1] + w * std::sin(w * t)) / w);
    ++n;
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.message;
  EXPECT_EQ(n, 401);
  EXPECT_LT(worst, 1e-8);
}

TEST(Integrators, NanRightHandSideStopsWithNonFiniteAndKeepsTheLastFiniteState) {
  // ẋ = −x, but NaN from t = 0.3 on.
  OdeRhs f = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    dx = -x;
    if (t >= 0.3) dx[0] = kNaN;
  };
  {  // RK4 with h = 1/64: steps end on exactly representable times; the step 0.296875 → 0.3125
     // is the first one to evaluate at t ≥ 0.3.
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.t1 = 1.0;
    o.step = 1.0 / 64;
    std::vector<Sample> seen;
    auto s = integrate(f, x, o, [&](double t, const Eigen::VectorXd& xx) {
      seen.push_back({t, xx});
      return true;
    });
    EXPECT_EQ(s.status, IntegrationStatus::NonFinite);
    EXPECT_NE(s.message.find("0.296875"), std::string::npos) << s.message;
    EXPECT_NE(s.message.find("0.3125"), std::string::npos) << s.message;
    EXPECT_EQ(s.t_end, 0.296875);
    EXPECT_EQ(s.steps, 19);
    ASSERT_TRUE(x.allFinite());
    EXPECT_NEAR(x[0], std::exp(-0.296875), 1e-9);
    ASSERT_EQ(seen.size(), 20u);
    EXPECT_EQ(seen.back().t, 0.296875);
    EXPECT_EQ(seen.back().x, x);
  }
  {  // Dormand–Prince.
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = IntegratorMethod::DormandPrince45;
    o.t1 = 1.0;
    o.step = 1e-3;
    o.output_interval = 0.01;
    std::vector<Sample> seen;
    auto s = integrate(f, x, o, [&](double t, const Eigen::VectorXd& xx) {
      seen.push_back({t, xx});
      return true;
    });
    EXPECT_EQ(s.status, IntegrationStatus::NonFinite) << to_string(s.status) << ": " << s.message;
    EXPECT_NE(s.message.find("t = "), std::string::npos) << s.message;
    // The step that produced the NaN may have been long: the last finite state is somewhere
    // before 0.3 (0.21 here), not necessarily next to it.
    EXPECT_LT(s.t_end, 0.3);
    EXPECT_GT(s.t_end, 0.1);
    ASSERT_TRUE(x.allFinite());
    EXPECT_NEAR(x[0], std::exp(-s.t_end), 1e-7);
    ASSERT_GE(seen.size(), 11u);  // 0, 0.01, …, ≥ 0.1
    for (const Sample& sm : seen) {
      EXPECT_TRUE(sm.x.allFinite()) << sm.t;
      EXPECT_LE(sm.t, s.t_end);
      EXPECT_NEAR(sm.x[0], std::exp(-sm.t), 1e-7) << sm.t;
    }
  }
}

TEST(Integrators, NumericalFailureFromTheRightHandSideIsReported) {
  const std::string msg = "at t = 0.3 s the velocity partition is singular (test)";
  OdeRhs f = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    if (t >= 0.3) throw NumericalFailure(t, msg);
    dx = -x;
  };
  for (IntegratorMethod m : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45}) {
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = m;
    o.t1 = 1.0;
    o.step = 1.0 / 64;
    int seen = 0;
    double last_seen = -1;
    auto s = integrate(f, x, o, [&](double t, const Eigen::VectorXd&) {
      ++seen;
      last_seen = t;
      return true;
    });
    EXPECT_EQ(s.status, IntegrationStatus::NumericalFailure) << to_string(m);
    EXPECT_EQ(s.message, msg);
    EXPECT_FALSE(s.ok());
    EXPECT_LT(s.t_end, 0.3) << to_string(m);
    EXPECT_GT(s.t_end, 0.2) << to_string(m);
    ASSERT_TRUE(x.allFinite());
    EXPECT_NEAR(x[0], std::exp(-s.t_end), 1e-7) << to_string(m);
    EXPECT_GT(seen, 1);
    EXPECT_LE(last_seen, s.t_end);
  }
}

TEST(Integrators, FiniteTimeBlowUpStopsBeforeTheSingularity) {
  // ẋ = x², x(0) = 1: x = 1/(1 − t), infinite at t = 1.
  OdeRhs f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx = x.cwiseProduct(x); };
  {
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = IntegratorMethod::DormandPrince45;
    o.t1 = 2.0;
    o.step = 1e-3;
    auto s = integrate(f, x, o);
    EXPECT_TRUE(s.status == IntegrationStatus::StepSizeCollapse || s.status == IntegrationStatus::NonFinite)
        << to_string(s.status) << ": " << s.message;
    // The numerical solution blows up at 1 + O(accumulated error): with rtol = 1e-8 the run
    // stops within ~1e-9 of t = 1 (measured: 1 + 5.9e-10), with x ~ 1/(t* − t) ~ 6e10.
    EXPECT_LT(s.t_end, 1.0 + 1e-7);
    EXPECT_GT(s.t_end, 1.0 - 1e-7);
    EXPECT_TRUE(x.allFinite());
    EXPECT_GT(x[0], 1e3);
    EXPECT_LT(s.wall_time, 5.0);
    EXPECT_FALSE(s.message.empty());
    std::cout.precision(17);
    std::cout << "[ blow-up dopri ] " << to_string(s.status) << " at t_end = " << s.t_end << ", x = " << x[0]
              << ", steps " << s.steps << ": " << s.message << "\n";
  }
  {
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.t1 = 2.0;
    o.step = 1e-3;
    auto s = integrate(f, x, o);
    EXPECT_EQ(s.status, IntegrationStatus::NonFinite) << s.message;
    EXPECT_LT(s.t_end, 1.1);
    EXPECT_TRUE(x.allFinite());
  }
}

TEST(Integrators, ObserverReturningFalseStops) {
  for (IntegratorMethod m : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45}) {
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = m;
    o.t1 = 2.0;
    o.step = 1.0 / 64;
    o.output_interval = 0.125;
    std::vector<double> times;
    auto s = integrate(exponential(-1.0), x, o, [&](double t, const Eigen::VectorXd&) {
      times.push_back(t);
      return t < 0.5;
    });
    EXPECT_EQ(s.status, IntegrationStatus::Stopped) << to_string(m);
    EXPECT_NE(s.message.find("observer"), std::string::npos);
    EXPECT_EQ(times, (std::vector<double>{0.0, 0.125, 0.25, 0.375, 0.5})) << to_string(m);
    EXPECT_GE(s.t_end, 0.5);
    EXPECT_LT(s.t_end, 1.0);
    EXPECT_NEAR(x[0], std::exp(-s.t_end), 1e-7) << to_string(m);
    // Stop at the very first call.
    x[0] = 1.0;
    int calls = 0;
    s = integrate(exponential(-1.0), x, o, [&](double, const Eigen::VectorXd&) {
      ++calls;
      return false;
    });
    EXPECT_EQ(s.status, IntegrationStatus::Stopped);
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(s.steps, 0);
    EXPECT_EQ(x[0], 1.0);
  }
}

TEST(Integrators, MaxStepsIsReported) {
  for (IntegratorMethod m : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45}) {
    Eigen::VectorXd x(1);
    x[0] = 1.0;
    IntegratorOptions o;
    o.method = m;
    o.t1 = 10.0;
    o.step = 1e-3;
    o.rtol = 1e-12;
    o.atol = 1e-14;
    o.max_steps = 10;
    auto s = integrate(exponential(-1.0), x, o);
    EXPECT_EQ(s.status, IntegrationStatus::MaxSteps) << to_string(m);
    EXPECT_EQ(s.steps, 10);
    EXPECT_NE(s.message.find("max_steps"), std::string::npos);
    EXPECT_LT(s.t_end, 1.0);
    EXPECT_NEAR(x[0], std::exp(-s.t_end), 1e-10);
  }
}

TEST(Integrators, BadOptionsThrow) {
  auto run = [](IntegratorOptions o) {
    Eigen::VectorXd x = Eigen::VectorXd::Ones(1);
    integrate(exponential(-1.0), x, o);
  };
  IntegratorOptions o;
  o.t1 = o.t0;
  expect_error_mentioning([&] { run(o); }, {"t1"});
  o = {};
  o.t1 = -1.0;
  expect_error_mentioning([&] { run(o); }, {"t1"});
  o = {};
  o.t0 = kNaN;
  expect_error_mentioning([&] { run(o); }, {"t0"});
  o = {};
  o.step = 0.0;
  expect_error_mentioning([&] { run(o); }, {"step"});
  o = {};
  o.step = -1e-3;
  expect_error_mentioning([&] { run(o); }, {"step"});
  o = {};
  o.output_interval = -0.1;
  expect_error_mentioning([&] { run(o); }, {"output_interval"});
  o = {};
  o.rtol = 0.0;
  expect_error_mentioning([&] { run(o); }, {"rtol"});
  o = {};
  o.atol = kNaN;
  expect_error_mentioning([&] { run(o); }, {"atol"});
  o = {};
  o.min_step = o.step;
  expect_error_mentioning([&] { run(o); }, {"min_step"});
  o = {};
  o.max_steps = 0;
  expect_error_mentioning([&] { run(o); }, {"max_steps"});
  // Right-hand side missing, or a non-finite initial state.
  Eigen::VectorXd x = Eigen::VectorXd::Ones(2);
  expect_error_mentioning([&] { integrate(OdeRhs{}, x, IntegratorOptions{}); }, {"right-hand side"});
  x[1] = kNaN;
  expect_error_mentioning([&] { integrate(exponential(-1.0), x, IntegratorOptions{}); }, {"x0", "[1]"});
}

// Breakpoints (IntegratorOptions::breakpoints): ẋ = (t, a(t)) with a jumping from 1 to −2 at
// b = 0.3337 (a piecewise-linear ẋ₁: x₁ is piecewise quadratic, which RK4 integrates exactly on
// each part). With b a breakpoint every method lands on it and sees the left limit on the step
// that ends there: RK4 is exact to rounding, Dormand–Prince and BDF to their tolerance; without
// it RK4's step across b is off by O(h²). RK4's grid: equal steps per part, ends on b and t1,
// every step end a sample.
TEST(Integrators, BreakpointsAreLandedOnAndApproachedFromTheLeft) {
  const double b = 0.3337, t1 = 1.0;
  long right_at_b = 0;
  auto f = [&](double t, const Eigen::VectorXd&, Eigen::VectorXd& dx) {
    dx.resize(2);
    dx[0] = t < b ? 1.0 : -2.0;
    dx[1] = t < b ? t : -2.0 * t;
    if (t == b) ++right_at_b;
  };
  auto exact = [&](double t) {
    Eigen::Vector2d x;
    x[0] = t < b ? t : b - 2.0 * (t - b);
    x[1] = t < b ? 0.5 * t * t : 0.5 * b * b - (t * t - b * b);
    return x;
  };
  for (const IntegratorMethod method : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45, IntegratorMethod::BDF}) {
    SCOPED_TRACE(to_string(method));
    IntegratorOptions o;
    o.method = method;
    o.t0 = 0;
    o.t1 = t1;
    o.step = 0.05;
    o.breakpoints = {b};
    std::vector<double> ts;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(2);
    right_at_b = 0;
    const OdeJacobian jac = [](double, const Eigen::VectorXd&, Eigen::MatrixXd& J) { J = Eigen::MatrixXd::Zero(2, 2); };
    const IntegrationSummary s = integrate(f, x, o, [&](double t, const Eigen::VectorXd&) {
      ts.push_back(t);
      return true;
    }, jac);
    ASSERT_TRUE(s.ok()) << s.message;
    const double tol = method == IntegratorMethod::RK4 ? 1e-14 : method == IntegratorMethod::BDF ? 1e-6 : 1e-8;
    EXPECT_LE((x - exact(t1)).cwiseAbs().maxCoeff(), tol) << x.transpose() << " vs " << exact(t1).transpose();
    EXPECT_GE(right_at_b, 1);  // the step after b starts on b itself (the right-hand side there)
    if (method != IntegratorMethod::RK4) continue;
    const Rk4Grid grid(o);
    EXPECT_EQ(grid.steps(), 7 + 14);  // ⌈0.3337/0.05⌉ = 7 and ⌈0.6663/0.05⌉ = 14 steps
    EXPECT_EQ(grid.end(6), b);
    EXPECT_EQ(grid.end(grid.steps() - 1), t1);
    EXPECT_LT(grid.stage_time(6, 1.0), b);
    EXPECT_EQ(grid.start(7), b);
    ASSERT_EQ(ts.size(), static_cast<size_t>(grid.steps()) + 1);
    EXPECT_EQ(ts[7], b);
    // without the breakpoint the step across b loses RK4's exactness
    IntegratorOptions plain = o;
    plain.breakpoints.clear();
    Eigen::VectorXd y = Eigen::VectorXd::Zero(2);
    ASSERT_TRUE(integrate(f, y, plain).ok());
    EXPECT_GT((y - exact(t1)).cwiseAbs().maxCoeff(), 1e-5);
  }
}

// No stage is evaluated past t1: on the last step t + h can round one ulp above t1 (here
// t1 = 1.063 with step 0.05: (n − 1)·h + h = t1 + 2.2e-16, with and without a breakpoint), and a
// time law is at rest past its end, so such a stage saw s̈ = 0 instead of the final deceleration
// (+3.3 % effort at the last sample of the 8-part rotor: tests/phase_plane_test.cpp). The last
// stage of every RK4 step is at the step's end as the grid holds it (on a breakpoint: below it).
TEST(Integrators, NoStageIsEvaluatedPastT1) {
  const double t1 = 1.063;
  for (const bool with_break : {false, true}) {
    for (const IntegratorMethod method : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45}) {
      SCOPED_TRACE(std::string(to_string(method)) + (with_break ? ", breakpoint 0.3337" : ", no breakpoint"));
      IntegratorOptions o;
      o.method = method;
      o.t0 = 0;
      o.t1 = t1;
      o.step = 0.05;
      if (with_break) o.breakpoints = {0.3337};
      double latest = -1;
      auto f = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
        latest = std::max(latest, t);
        dx = -x;
      };
      Eigen::VectorXd x = Eigen::VectorXd::Ones(1);
      ASSERT_TRUE(integrate(f, x, o).ok());
      EXPECT_EQ(latest, t1);
      if (method != IntegratorMethod::RK4) continue;
      const Rk4Grid grid(o);
      const long last = grid.steps() - 1;
      EXPECT_GT(grid.start(last) + grid.size(last), t1);  // the rounding this test is about
      for (long k = 0; k < grid.steps(); ++k) EXPECT_LE(grid.stage_time(k, 1.0), grid.end(k)) << "step " << k;
    }
  }
}
