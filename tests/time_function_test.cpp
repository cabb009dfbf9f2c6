// Time functions: exact first and second derivatives against central finite differences, the
// cycloidal rise's boundary conditions, and parameter validation.
//
// FD budget: central difference with step h on |f| ~ 1..10: truncation h²|f'''|/6 ~ 1e-10·|f'''|,
// rounding ε|f|/h ~ 1e-10. The tolerance 1e-7 (relative to max(|f'|, 1)) leaves ~100× margin
// for the largest third derivatives used here (|f'''| ≲ 100).
#include "refdyn/common/error.hpp"
#include "refdyn/expression/time_function.hpp"
#include "test_support.hpp"

#include <cmath>
#include <limits>
#include <numbers>

using namespace refdyn;
using refdyn::test::near;

namespace {

constexpr double kH = 1e-5;
constexpr double kTol = 1e-7;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Named {
  std::string label;
  TimeFunctionPtr f;
};

std::vector<Named> zoo() {
  return {
      {"constant", constant(2.5)},
      {"polynomial", polynomial({0.3, -1.2, 0.7, 0.25, -0.05})},
      {"polynomial_empty", polynomial({})},
      {"sinusoid", sinusoid(0.8, 3.1, 0.4, -0.2)},
      {"raised_cosine", raised_cosine(1.0, 0.1, 5.0)},
      {"raised_cosine_fast", raised_cosine(-0.4, 2.0, 0.7)},
      {"cycloidal", cycloidal(2 * std::numbers::pi, 5.0)},
      {"cycloidal_shifted", cycloidal(-1.5, 0.8, 0.3, 0.6)},
  };
}

void expect_derivatives_match_fd(const Named& n, double t) {
  const TimeValue v = n.f->eval(t);
  const TimeValue p = n.f->eval(t + kH), m = n.f->eval(t - kH);
  const double fd1 = (p.f - m.f) / (2 * kH);
  const double fd2 = (p.df - m.df) / (2 * kH);
  EXPECT_NEAR(v.df, fd1, kTol * std::max(1.0, std::abs(v.df))) << n.label << " at t = " << t;
  EXPECT_NEAR(v.ddf, fd2, kTol * std::max(1.0, std::abs(v.ddf))) << n.label << " at t = " << t;
  // Second difference of f itself (independent of df): rounding ~ε|f|/h², use h = 1e-4.
  const double h2 = 1e-4;
  const double fdd = (n.f->eval(t + h2).f - 2 * v.f + n.f->eval(t - h2).f) / (h2 * h2);
  EXPECT_NEAR(v.ddf, fdd, 1e-4 * std::max(1.0, std::abs(v.ddf))) << n.label << " at t = " << t;
}

}  // namespace

TEST(TimeFunction, DerivativesMatchFiniteDifferencesAtRandomTimes) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ut(-1.0, 7.0);
  for (const Named& n : zoo()) {
    for (int k = 0; k < 50; ++k) {
      double t = ut(rng);
      // Stay away from the cycloidal's switch points: f is C2 there but f''' jumps, so a stencil
      // straddling one is only first-order accurate.
      if (n.label.rfind("cycloidal", 0) == 0) {
        if (std::abs(t - 0.0) < 1e-3 || std::abs(t - 5.0) < 1e-3 || std::abs(t - 0.6) < 1e-3 ||
            std::abs(t - 1.4) < 1e-3)
          continue;
      }
      expect_derivatives_match_fd(n, t);
    }
    EXPECT_FALSE(n.f->describe().empty()) << n.label;
  }
}

TEST(TimeFunction, ValuesMatchTheirFormulas) {
  const double t = 0.73;
  EXPECT_EQ(constant(2.5)->eval(t).f, 2.5);
  EXPECT_EQ(constant(2.5)->eval(t).df, 0.0);
  const TimeValue p = polynomial({0.3, -1.2, 0.7, 0.25})->eval(t);
  EXPECT_NEAR(p.f, 0.3 - 1.2 * t + 0.7 * t * t + 0.25 * t * t * t, 1e-15);
  EXPECT_NEAR(p.df, -1.2 + 1.4 * t + 0.75 * t * t, 1e-15);
  EXPECT_NEAR(p.ddf, 1.4 + 1.5 * t, 1e-15);
  const TimeValue e = polynomial({})->eval(t);
  EXPECT_EQ(e.f, 0.0);
  EXPECT_EQ(e.df, 0.0);
  EXPECT_EQ(e.ddf, 0.0);
  const TimeValue s = sinusoid(0.8, 3.1, 0.4, -0.2)->eval(t);
  EXPECT_NEAR(s.f, -0.2 + 0.8 * std::sin(3.1 * t + 0.4), 1e-15);
  EXPECT_NEAR(s.df, 0.8 * 3.1 * std::cos(3.1 * t + 0.4), 1e-14);
  EXPECT_NEAR(s.ddf, -0.8 * 3.1 * 3.1 * std::sin(3.1 * t + 0.4), 1e-14);
  // The spec's z_a(t): starts at f0 with zero velocity, peaks at f0 + Δz at T/2.
  auto za = raised_cosine(1.0, 0.1, 5.0);
  EXPECT_NEAR(za->eval(0).f, 1.0, 1e-15);
  EXPECT_NEAR(za->eval(0).df, 0.0, 1e-15);
  EXPECT_NEAR(za->eval(2.5).f, 1.1, 1e-15);
  EXPECT_NEAR(za->eval(5.0).f, 1.0, 1e-15);
  EXPECT_NEAR(za->eval(t).f, 1.0 + 0.1 * (1 - std::cos(2 * std::numbers::pi * t / 5)) / 2, 1e-15);
}

TEST(TimeFunction, CycloidalEndpointsAndPlateaus) {
  const double rise = -1.5, dur = 0.8, f0 = 0.3, t0 = 0.6;
  auto c = cycloidal(rise, dur, f0, t0);
  // At and before the start: f0, at rest.
  for (double t : {t0 - 10.0, t0 - 1e-3, t0}) {
    const TimeValue v = c->eval(t);
    EXPECT_EQ(v.f, f0) << t;
    EXPECT_EQ(v.df, 0.0) << t;
    EXPECT_EQ(v.ddf, 0.0) << t;
  }
  // After the end: f0 + rise, at rest.
  for (double t : {t0 + dur + 1e-3, t0 + 100.0}) {
    const TimeValue v = c->eval(t);
    EXPECT_NEAR(v.f, f0 + rise, 1e-15) << t;
    EXPECT_EQ(v.df, 0.0) << t;
    EXPECT_EQ(v.ddf, 0.0) << t;
  }
  // At the end itself ((t − t0)/dur may round to 1 − ε): the same to rounding.
  {
    const TimeValue v = c->eval(t0 + dur);
    EXPECT_NEAR(v.f, f0 + rise, 1e-15);
    EXPECT_NEAR(v.df, 0.0, 1e-15);
    EXPECT_NEAR(v.ddf, 0.0, 1e-12);
  }
  // Continuity of f, f', f'' at both ends from inside (f'' → 0 linearly, f' quadratically).
  const double e = 1e-7;
  for (double t : {t0 + e, t0 + dur - e}) {
    const TimeValue v = c->eval(t);
    const double f_end = t < t0 + dur / 2 ? f0 : f0 + rise;
    EXPECT_NEAR(v.f, f_end, 1e-12) << t;
    EXPECT_NEAR(v.df, 0.0, 1e-11) << t;
    // |f''| ≈ 4π²|rise|·e/dur³ (≈ 1.2e-5 here) against a peak of 2π|rise|/dur² ≈ 14.7.
    const double bound = 4 * std::numbers::pi * std::numbers::pi * std::abs(rise) * e / (dur * dur * dur);
    EXPECT_LE(std::abs(v.ddf), 1.001 * bound) << t;
  }
  // Midpoint: half the rise, peak velocity 2·rise/dur, zero acceleration.
  const TimeValue mid = c->eval(t0 + dur / 2);
  EXPECT_NEAR(mid.f, f0 + rise / 2, 1e-15);
  EXPECT_NEAR(mid.df, 2 * rise / dur, 1e-14);
  EXPECT_NEAR(mid.ddf, 0.0, 1e-12);
  // Monotone rise (rise < 0: decreasing).
  double prev = c->eval(t0).f;
  for (int k = 1; k <= 100; ++k) {
    const double f = c->eval(t0 + dur * k / 100.0).f;
    EXPECT_LE(f, prev + 1e-15);
    prev = f;
  }
  // The paper's drive: 2π over 5 s from 0.
  auto d = cycloidal(2 * std::numbers::pi, 5.0);
  EXPECT_NEAR(d->eval(5.0).f, 2 * std::numbers::pi, 1e-15);
  EXPECT_NEAR(d->eval(2.5).f, std::numbers::pi, 1e-15);
  EXPECT_NEAR(d->eval(1.0).f, 2 * std::numbers::pi * (0.2 - std::sin(0.4 * std::numbers::pi) / (2 * std::numbers::pi)),
              1e-15);
}

TEST(TimeFunction, BadParametersThrowWithMessages) {
  auto throws_with = [](auto&& fn, const std::string& needle) {
    try {
      fn();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << "expected refdyn::Error mentioning '" << needle << "'";
  };
  throws_with([] { constant(kNaN); }, "constant");
  throws_with([] { polynomial({1.0, kInf}); }, "polynomial");
  throws_with([] { sinusoid(1.0, kNaN); }, "sinusoid");
  throws_with([] { raised_cosine(0.0, 1.0, 0.0); }, "period");
  throws_with([] { raised_cosine(0.0, 1.0, -2.0); }, "period");
  throws_with([] { raised_cosine(kNaN, 1.0, 2.0); }, "raised_cosine");
  throws_with([] { cycloidal(1.0, 0.0); }, "duration");
  throws_with([] { cycloidal(1.0, -1.0); }, "duration");
  throws_with([] { cycloidal(1.0, 1.0, kInf); }, "cycloidal");
}

// Expression time functions (expression_time_function, built on refdyn::Expression).

TEST(ExpressionTimeFunction, ProgrammedSpeedIsFiniteAtTheKink) {
  // The issue: an RK4 stage landing exactly on t = 2 saw NaN from min(t, 2).
  const auto f = expression_time_function("(1 - cos(pi*min(t, 2)/2))/2");
  const double pi = std::numbers::pi;
  const TimeValue k = f->eval(2.0);
  ASSERT_TRUE(std::isfinite(k.f) && std::isfinite(k.df) && std::isfinite(k.ddf));
  // At t = 2 the rising branch (min's first argument wins ties): its one-sided derivatives.
  EXPECT_NEAR(k.f, 1.0, 1e-15);
  EXPECT_NEAR(k.df, pi / 4 * std::sin(pi), 1e-15);
  EXPECT_NEAR(k.ddf, pi * pi / 8 * std::cos(pi), 1e-14);
  // After: constant 1.
  const TimeValue a = f->eval(2.5);
  EXPECT_EQ(a.f, 1.0);
  EXPECT_EQ(a.df, 0.0);
  EXPECT_EQ(a.ddf, 0.0);
  // Before: finite differences agree with the exact derivatives.
  expect_derivatives_match_fd({"speed", f}, 1.3);
  expect_derivatives_match_fd({"speed_after", f}, 2.7);
}

TEST(ExpressionTimeFunction, ZeroAmplitudeGivesAConstant) {
  // amp = 0 removes t from amp*sin(t) after substitution: a constant function, not an error.
  const auto f = expression_time_function("amp*sin(t)", {{"amp", 0.0}});
  for (double t : {0.0, 0.7, 3.0}) {
    const TimeValue v = f->eval(t);
    EXPECT_EQ(v.f, 0.0);
    EXPECT_EQ(v.df, 0.0);
    EXPECT_EQ(v.ddf, 0.0);
  }
  const auto g = expression_time_function("z0 + amp*sin(w*t)", {{"z0", 0.5}, {"amp", 0.0}, {"w", 2.0}});
  EXPECT_EQ(g->eval(1.0).f, 0.5);
  EXPECT_EQ(g->eval(1.0).df, 0.0);
}
