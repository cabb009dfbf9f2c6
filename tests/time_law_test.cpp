// The time law s(t) of a scenario's `time_law:` (expression/time_law.hpp): monotone, C¹ and
// exact at the ends by construction; f(s(t)) with exact chain-rule derivatives; its symbolic
// text (parsed back by the expression engine, which differentiates it with GiNaC) equal to the
// numeric law; scenario reading and its bad input; `refdyn generate` on the retimed example;
// and the independent time-optimal reference (topp_reference.hpp) of examples/planar_2r_circle.
//
// FD budget: central differences with h = 1e-6 inside a segment (never across a knot, where s̈
// jumps): truncation h²|f'''|/6 ≲ 1e-10, rounding ε|f|/h ≲ 1e-9 for |f| ≲ 10; tolerance 1e-6
// relative to max(|f'|, 1).
#include "refdyn/common/error.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/scenario/problem.hpp"
#include "test_support.hpp"
#include "topp_reference.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include "refdyn/common/text.hpp"
#include <sys/wait.h>

using namespace refdyn;
namespace fs = std::filesystem;

namespace {

std::vector<Number> random_segments(std::mt19937& rng, int K) {
  // durations over almost two decades, so that the slope limiter (3·min δ) is active at some knots
  std::uniform_real_distribution<double> U(std::log(0.02), std::log(1.5));
  std::vector<Number> d;
  for (int i = 0; i < K; ++i) d.emplace_back(std::exp(U(rng)));
  return d;
}

const std::string kExample = std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/retime.yaml";

std::string example_text() { return test::read_file(kExample); }

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto p = s.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  if (p != std::string::npos) s.replace(p, from.size(), to);
  return s;
}

}  // namespace

TEST(TimeLaw, MonotoneC1AndExactEndsForRandomSegments) {
  std::mt19937 rng(23);
  for (int trial = 0; trial < 50; ++trial) {
    const int K = 1 + trial % 20;
    const double Tp = 0.1 + 3.0 * std::uniform_real_distribution<double>(0, 1)(rng);
    const TimeLaw law(Tp, random_segments(rng, K));
    const double T = law.end_time();
    EXPECT_EQ(law.eval(0).s, 0.0);
    EXPECT_EQ(law.eval(T).s, Tp);  // exactly, by construction
    EXPECT_EQ(law.eval(0).ds, 0.0);
    EXPECT_EQ(law.eval(T).ds, 0.0);
    EXPECT_EQ(law.eval(T + 1).s, Tp);
    EXPECT_EQ(law.eval(-1).s, 0.0);
    // just below the end: the last cubic reaches Tp with slope 0
    EXPECT_NEAR(law.eval(T * (1 - 1e-12)).s, Tp, 1e-9 * Tp);
    // monotone: ṡ ≥ 0 and s non-decreasing on a fine grid
    double prev = -1;
    for (int k = 0; k <= 20000; ++k) {
      const TimeLawValue v = law.eval(T * k / 20000.0);
      EXPECT_GE(v.ds, 0.0);
      EXPECT_GE(v.s, prev);
      prev = v.s;
    }
    // C¹ at the interior knots: left and right limits of s and ṡ agree; s(t_i) = i Tp/K
    for (int i = 1; i < K; ++i) {
      const double ti = law.knots()[i], e = 1e-9 * std::max(1.0, ti);
      const TimeLawValue l = law.eval(ti - e), r = law.eval(ti + e), at = law.eval(ti);
      EXPECT_NEAR(at.s, i * Tp / K, 1e-12 * Tp);
      // across [ti − e, ti + e] a C¹ function changes s by ≲ e(|ṡ_l| + |ṡ_r|) and ṡ by ≲ e(|s̈_l| + |s̈_r|)
      // (a jump of ṡ would show as a difference of order 1)
      EXPECT_LE(std::abs(l.s - r.s), e * (std::abs(l.ds) + std::abs(r.ds)) * 1.01 + 1e-15);
      EXPECT_LE(std::abs(l.ds - r.ds), e * (std::abs(l.dds) + std::abs(r.dds)) * 1.01 + 1e-12);
      EXPECT_NEAR(at.ds, law.slope(i), 1e-12 * (1 + law.slope(i)));
      EXPECT_GT(law.slope(i), 0.0);
      const double di = law.knots()[i] - law.knots()[i - 1], dn = law.knots()[i + 1] - law.knots()[i];
      EXPECT_LE(law.slope(i), 3 * (Tp / K) / std::max(di, dn) * (1 + 1e-12));  // the Fritsch–Carlson limit (d from knot differences: rounding)
    }
  }
}

TEST(TimeLaw, UniformAccelerationIsReproducedExactly) {
  // s = a t²/2 cut into K equal parts of τ: d_i = √(2iΔτ/a) − √(2(i−1)Δτ/a). The parabola slope
  // of every inner knot is exact (a t_i, within the limiter's 3·min δ), the first part starts
  // with slope 0 as s does, so the cubic pieces are s itself on the first K − 1 parts.
  const double a = 3.0, Tp = 2.0;
  const int K = 10;
  std::vector<Number> d;
  for (int i = 1; i <= K; ++i) d.emplace_back(std::sqrt(2 * i * Tp / K / a) - std::sqrt(2 * (i - 1) * Tp / K / a));
  const TimeLaw law(Tp, d);
  for (int i = 1; i < K; ++i) EXPECT_NEAR(law.slope(i), a * law.knots()[i], 1e-12);
  for (int k = 0; k < 1000; ++k) {
    const double t = law.knots()[K - 1] * k / 1000.0;
    const TimeLawValue v = law.eval(t);
    EXPECT_NEAR(v.s, a * t * t / 2, 1e-12);
    EXPECT_NEAR(v.ds, a * t, 1e-11);
    EXPECT_NEAR(v.dds, a, 1e-9);
  }
}

TEST(TimeLaw, EqualSegmentsOfTpOverKAreTheIdentityAwayFromTheEnds) {
  // Interior slopes Δτ(d² + d²)/(d·d·2d) = 1: the Hermite cubic through linear data with slopes 1 is the
  // line itself, so s(t) = t on [Tp/K, Tp − Tp/K]; only the first and last parts (rest to rest,
  // ṡ = 0 at the ends) differ from the identity.
  const double Tp = 2.0;
  const int K = 16;
  const TimeLaw law(Tp, std::vector<Number>(K, Number(Tp / K)));
  for (int i = 1; i < K; ++i) EXPECT_DOUBLE_EQ(law.slope(i), 1.0);
  for (int k = 0; k < 1000; ++k) {  // [Tp/K, Tp − Tp/K): at Tp − Tp/K the last part starts (s̈ jumps)
    const double t = Tp / K + (Tp - 2 * Tp / K) * k / 1000.0;
    const TimeLawValue v = law.eval(t);
    EXPECT_NEAR(v.s, t, 1e-14);
    EXPECT_NEAR(v.ds, 1.0, 1e-13);
    EXPECT_NEAR(v.dds, 0.0, 1e-10);
  }
  EXPECT_GT(std::abs(law.eval(0.5 * Tp / K).s - 0.5 * Tp / K), 1e-3);  // the ends are not the identity
}

TEST(TimeLaw, DerivativesOfTheLawAndOfTheRetimedFunctionMatchFiniteDifferences) {
  std::mt19937 rng(7);
  const auto law = std::make_shared<const TimeLaw>(Number(2.0), random_segments(rng, 9));
  const TimeFunctionPtr inner = expression_time_function("0.6 + 0.15*cos(2*pi*t/2) + 0.3*t^3");
  const TimeFunctionPtr f = time_law_function(inner, law);
  const double h = 1e-6;
  std::uniform_real_distribution<double> U(0, 1);
  int checked = 0;
  for (int k = 0; k < 400; ++k) {
    const int i = 1 + static_cast<int>(U(rng) * law->segments()) % law->segments();
    const double a = law->knots()[i - 1], b = law->knots()[i];
    const double t = a + (b - a) * (0.05 + 0.9 * U(rng));  // well inside a segment
    const TimeLawValue v = law->eval(t), vp = law->eval(t + h), vm = law->eval(t - h);
    EXPECT_NEAR(v.ds, (vp.s - vm.s) / (2 * h), 1e-6 * std::max(1.0, std::abs(v.ds)));
    EXPECT_NEAR(v.dds, (vp.ds - vm.ds) / (2 * h), 1e-6 * std::max(1.0, std::abs(v.dds)));
    EXPECT_NEAR(v.ddds, (vp.dds - vm.dds) / (2 * h), 1e-6 * std::max(1.0, std::abs(v.ddds)));
    const TimeValue g = f->eval(t), gp = f->eval(t + h), gm = f->eval(t - h);
    EXPECT_DOUBLE_EQ(g.f, inner->eval(v.s).f);
    EXPECT_NEAR(g.df, (gp.f - gm.f) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.df)));
    EXPECT_NEAR(g.ddf, (gp.df - gm.df) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.ddf)));
    EXPECT_NEAR(g.dddf, (gp.ddf - gm.ddf) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.dddf)));
    ++checked;
  }
  EXPECT_EQ(checked, 400);
}

/// The law's symbolic text (every parameter a symbol of it) evaluated by the expression engine
/// gives the numeric law's s, ṡ, s̈, s⃛ on a grid past both ends, and the retimed function's
/// symbolic form gives the same f, ḟ, f̈.
namespace {
void expect_symbolic_law_matches(const std::shared_ptr<const TimeLaw>& law, const std::map<std::string, double>& params) {
  const std::string text = law->symbolic_text();
  for (const auto& [name, v] : params) EXPECT_TRUE(uses_identifier(text, name)) << name;
  const TimeFunctionPtr sym = expression_time_function(text, params);
  const TimeFunctionPtr f = time_law_function(expression_time_function("sin(2*pi*t/Tp)", params), law);
  const std::optional<SymbolicForm> form = f->symbolic();
  ASSERT_TRUE(form);
  ASSERT_EQ(form->rows.size(), 1u);
  EXPECT_TRUE(form->scenario_texts);
  const TimeFunctionPtr fsym = expression_time_function(form->rows[0], params);
  for (int k = 0; k <= 500; ++k) {
    const double t = -0.1 + (law->end_time() + 0.2) * k / 500.0;
    const TimeLawValue v = law->eval(t);
    const TimeValue s = sym->eval(t);
    const double tol = 1e-9;
    EXPECT_NEAR(s.f, v.s, tol);
    EXPECT_NEAR(s.df, v.ds, tol * (1 + std::abs(v.ds)));
    EXPECT_NEAR(s.ddf, v.dds, tol * (1 + std::abs(v.dds)));
    EXPECT_NEAR(s.dddf, v.ddds, tol * (1 + std::abs(v.ddds)));
    const TimeValue a = f->eval(t), b = fsym->eval(t);
    EXPECT_NEAR(a.f, b.f, tol);
    EXPECT_NEAR(a.df, b.df, tol * (1 + std::abs(a.df)));
    EXPECT_NEAR(a.ddf, b.ddf, tol * (1 + std::abs(a.ddf)));
  }
}
}  // namespace

TEST(TimeLaw, SymbolicTextWithParameterNamesIsTheNumericLaw) {
  // The durations and Tp written as parameter names: the text parses back (expression engine,
  // GiNaC) to the same s, ṡ, s̈, s⃛, and the retimed function's symbolic form to the same f.
  std::mt19937 rng(11);
  const int K = 7;
  std::map<std::string, double> params{{"Tp", 1.7}};
  std::vector<Number> d;
  for (const Number& x : random_segments(rng, K)) {
    const std::string name = "d" + std::to_string(d.size() + 1);
    params[name] = x.value;
    d.emplace_back(x.value, name);
  }
  expect_symbolic_law_matches(std::make_shared<const TimeLaw>(Number(1.7, "Tp"), d), params);
}

TEST(TimeLaw, IdentifierReplacementIsWholeWordAndSkipsCalls) {
  EXPECT_EQ(replace_identifier("t + tt*t2 + sqrt(t) + x(t)", "t", "S"), "(S) + tt*t2 + sqrt((S)) + x((S))");
  EXPECT_TRUE(uses_identifier("1e-3*t", "t"));
  EXPECT_FALSE(uses_identifier("Tp + t1 + tau", "t"));
  EXPECT_FALSE(uses_identifier("t(3)", "t"));
}

TEST(TimeLaw, BadLawsThrow) {
  test::expect_error_mentioning([] { TimeLaw(0.0, {Number(1.0)}); }, {"task_duration", "> 0"});
  test::expect_error_mentioning([] { TimeLaw(1.0, {}); }, {"segments", "empty"});
  test::expect_error_mentioning([] { TimeLaw(1.0, {Number(1.0), Number(-0.5)}); }, {"segment 2", "> 0"});
}

// ---- the knot_speeds form (TOPP-RA discretisation) ----

namespace {
std::vector<Number> random_speeds(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> U(std::log(0.05), std::log(5.0));
  std::vector<Number> v;
  for (int i = 0; i < n; ++i) v.emplace_back(std::exp(U(rng)));
  return v;
}
}  // namespace

TEST(TimeLawKnotSpeeds, MonotoneC1ExactEndAndKnotSpeeds) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 50; ++trial) {
    const int K = 2 + trial % 30;
    const double Tp = 0.1 + 3.0 * std::uniform_real_distribution<double>(0, 1)(rng);
    const std::vector<Number> v = random_speeds(rng, K - 1);
    const TimeLaw law(TimeLawForm::knot_speeds, Tp, v);
    ASSERT_EQ(law.segments(), K);
    const double dtau = Tp / K;
    // end = Σ 2Δτ/(v_i + v_{i+1}), v_0 = v_K = 0
    double end = 0;
    for (int i = 0; i < K; ++i) end += 2 * dtau / ((i ? v[i - 1].value : 0.0) + (i + 1 < K ? v[i].value : 0.0));
    EXPECT_NEAR(law.end_time(), end, 1e-12 * end);
    EXPECT_EQ(law.eval(0).s, 0);
    EXPECT_EQ(law.eval(0).ds, 0);
    EXPECT_EQ(law.eval(law.end_time()).s, Tp);
    EXPECT_EQ(law.eval(-1).s, 0);
    EXPECT_EQ(law.eval(law.end_time() + 1).s, Tp);
    for (int i = 0; i <= K; ++i) {
      const double ti = law.knots()[i];
      const TimeLawValue left = law.eval(std::nextafter(ti, -1.0)), at = law.eval(ti);
      EXPECT_NEAR(at.s, dtau * i, 1e-12 * Tp) << "knot " << i;  // τ_i reached at t_i
      if (i > 0 && i < K) {
        EXPECT_NEAR(at.ds, v[i - 1].value, 1e-12 * (1 + v[i - 1].value));  // ṡ(t_i) = v_i, from both sides
        EXPECT_NEAR(left.ds, v[i - 1].value, 1e-9 * (1 + v[i - 1].value));
        EXPECT_NEAR(left.s, at.s, 1e-12 * Tp);
        EXPECT_EQ(law.slope(i), v[i - 1].value);
      }
    }
    double prev = -1;
    for (int k = 0; k <= 2000; ++k) {
      const TimeLawValue x = law.eval(law.end_time() * k / 2000.0);
      EXPECT_GE(x.s, prev);
      EXPECT_GE(x.ds, 0);
      EXPECT_EQ(x.ddds, 0);
      prev = x.s;
    }
  }
}

TEST(TimeLawKnotSpeeds, ConstantAccelerationPerPartAndDerivativesMatchFiniteDifferences) {
  std::mt19937 rng(31);
  const auto law = std::make_shared<const TimeLaw>(TimeLawForm::knot_speeds, Number(2.0), random_speeds(rng, 11));
  const double dtau = 2.0 / 12;
  const TimeFunctionPtr inner = expression_time_function("0.6 + 0.15*cos(2*pi*t/2) + 0.3*t^3");
  const TimeFunctionPtr f = time_law_function(inner, law);
  const double h = 1e-6;
  std::uniform_real_distribution<double> U(0, 1);
  for (int k = 0; k < 400; ++k) {
    const int i = 1 + static_cast<int>(U(rng) * law->segments()) % law->segments();
    const double a = law->knots()[i - 1], b = law->knots()[i];
    const double t = a + (b - a) * (0.05 + 0.9 * U(rng));
    const TimeLawValue v = law->eval(t), vp = law->eval(t + h), vm = law->eval(t - h);
    const double va = law->slope(i - 1), vb = law->slope(i);
    EXPECT_NEAR(v.dds, (vb * vb - va * va) / (2 * dtau), 1e-12 * (1 + std::abs(v.dds)));
    EXPECT_NEAR(b - a, 2 * dtau / (va + vb), 1e-12 * (b - a));
    EXPECT_NEAR(v.ds, (vp.s - vm.s) / (2 * h), 1e-6 * std::max(1.0, std::abs(v.ds)));
    EXPECT_NEAR(v.dds, (vp.ds - vm.ds) / (2 * h), 1e-6 * std::max(1.0, std::abs(v.dds)));
    const TimeValue g = f->eval(t), gp = f->eval(t + h), gm = f->eval(t - h);
    EXPECT_DOUBLE_EQ(g.f, inner->eval(v.s).f);
    EXPECT_NEAR(g.df, (gp.f - gm.f) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.df)));
    EXPECT_NEAR(g.ddf, (gp.df - gm.df) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.ddf)));
    EXPECT_NEAR(g.dddf, (gp.ddf - gm.ddf) / (2 * h), 1e-6 * std::max(1.0, std::abs(g.dddf)));
  }
}

TEST(TimeLawKnotSpeeds, SymbolicTextAndEndTextWithParameterNamesAreTheNumericLaw) {
  std::mt19937 rng(37);
  const int K = 9;
  std::map<std::string, double> params{{"Tp", 1.7}};
  std::vector<Number> v;
  for (const Number& x : random_speeds(rng, K - 1)) {
    const std::string name = "v" + std::to_string(v.size() + 1);
    params[name] = x.value;
    v.emplace_back(x.value, name);
  }
  const auto law = std::make_shared<const TimeLaw>(TimeLawForm::knot_speeds, Number(1.7, "Tp"), v);
  EXPECT_NEAR(expression_time_function(law->end_text(), params)->eval(0).f, law->end_time(), 1e-12 * law->end_time());
  expect_symbolic_law_matches(law, params);  // s⃛ = 0 here: the numeric law's ddds is 0
}

TEST(TimeLawKnotSpeeds, BadLawsThrow) {
  test::expect_error_mentioning([] { TimeLaw(TimeLawForm::knot_speeds, 0.0, {Number(1.0)}); }, {"task_duration", "> 0"});
  test::expect_error_mentioning([] { TimeLaw(TimeLawForm::knot_speeds, 1.0, {}); }, {"knot_speeds", "empty"});
  test::expect_error_mentioning([] { TimeLaw(TimeLawForm::knot_speeds, 1.0, {Number(1.0), Number(0.0)}); },
                                {"knot speed 2", "> 0"});
  test::expect_error_mentioning([] { TimeLaw(TimeLawForm::knot_speeds, 1.0, {Number(std::nan(""))}); },
                                {"knot speed 1", "> 0"});
}

namespace {
/// The knot-speed example in the old form: 127 scalar parameters v1 … v127 listed by name (the
/// example itself is in the compact form, one list parameter v).
const std::string kSpeedsExample = std::string(REFDYN_SOURCE_DIR) + "/tests/data/good/retime_speeds_old_form.yaml";
const std::string kCompactExample = std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/retime_speeds.yaml";

/// The 1-based line of the first occurrence of `part` in `text`.
int line_of(const std::string& text, const std::string& part) {
  const size_t at = text.find(part);
  EXPECT_NE(at, std::string::npos) << part;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(std::min(at, text.size())), '\n'));
}
}

// Issue 34, item 6: the compact form (knot_speeds: v, a list parameter) builds the same law as
// the old form (127 scalar parameters listed by name), to the bit: the same knots and the same
// law at every knot and between knots.
TEST(TimeLawKnotSpeeds, CompactFormIsTheSameLawAsTheOldForm) {
  const auto old_form = io::load_problem(kSpeedsExample);
  const auto compact = io::load_problem(kCompactExample);
  ASSERT_EQ(compact->time_law_knots.size(), 129u);
  EXPECT_EQ(compact->time_law_knots, old_form->time_law_knots);
  EXPECT_EQ(compact->integrator.t1, old_form->integrator.t1);
  // a list parameter's elements are numbers to the symbolic layer: the end's text has no v
  EXPECT_EQ(compact->texts.t1.find("v"), std::string::npos) << compact->texts.t1.substr(0, 80);
  // and a list with other values (an optimize candidate) is the law of those values
  const std::string text = test::read_file(kCompactExample);
  std::string list = "v: [";
  for (int i = 1; i <= 127; ++i) list += fmt(0.3 + 0.01 * i) + (i < 127 ? ", " : "]\n  old_v: [");
  const std::string varied = replaced(text, "v: [", list);
  const auto p = io::parse_problem(varied, "varied.yaml");
  const double dtau = 2.0 / 128;
  double end = 2 * dtau / 0.31 + 2 * dtau / (0.3 + 0.01 * 127);
  for (int i = 1; i < 127; ++i) end += 2 * dtau / ((0.3 + 0.01 * i) + (0.3 + 0.01 * (i + 1)));
  EXPECT_NEAR(p->integrator.t1, end, 1e-12 * end);
}

// The segments form takes a list parameter too: segments: d.
TEST(TimeLawScenario, SegmentsFromAListParameter) {
  std::string text = example_text();
  const std::string seg = "segments: [d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12, d13, d14, d15, d16]";
  ASSERT_NE(text.find(seg), std::string::npos);
  const auto a = io::parse_problem(text, "retime.yaml");
  text = replaced(text, seg, "segments: dl");
  text = replaced(text, "\nmodel:", "\n  dl: [d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12, d13, d14, d15, d16]\nmodel:");
  const auto b = io::parse_problem(text, "retime.yaml");
  EXPECT_EQ(a->time_law_knots, b->time_law_knots);
}

// Issue 34, bad input of the compact form: one located error line (file:line, key).
TEST(TimeLawKnotSpeeds, CompactFormBadInputIsOneLocatedError) {
  const std::string base = test::read_file(kCompactExample);
  const std::string src = "retime_speeds.yaml";
  auto expect_bad = [&](const std::string& yaml, const std::vector<std::string>& needles) {
    test::expect_error_mentioning([&] { (void)io::parse_problem(yaml, src); }, needles);
  };
  const std::string first = "v: [0.5, 0.5, 0.5,";
  // a knot speed ≤ 0 inside the law: the element's own line and index
  {
    const std::string yaml = replaced(base, "      0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,\n      0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,\n      0.5, 0.5, 0.5,",
                                      "      0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,\n      0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,\n      0.5, 0.5, -0.1,");
    const int line = line_of(base, first) + 3;
    expect_bad(yaml, {"retime_speeds.yaml:" + std::to_string(line) + ":", "parameters.v[50]", "knot speed", "> 0", "-0.1"});
    expect_bad(replaced(base, first, "v: [0.5, 0, 0.5,"),
               {"retime_speeds.yaml:" + std::to_string(line_of(base, first)) + ":", "parameters.v[1]", "> 0"});
  }
  // an empty list, or one beyond the bound on list parameters
  expect_bad(replaced(base, "  v: [", "  v: []\n  w: ["), {"retime_speeds.yaml:" + std::to_string(line_of(base, first)) + ":", "parameters.v", "empty"});
  {
    std::string huge = "v: [";
    for (size_t i = 0; i <= kMaxListParameter; ++i) huge += i ? ",1" : "1";
    expect_bad(replaced(base, "v: [", huge + "]\n  w: ["), {"retime_speeds.yaml:", "parameters.v", "at most 100000", "100001"});
  }
  // knot_speeds naming a parameter that is no list, or no parameter
  expect_bad(replaced(base, "knot_speeds: v ", "knot_speeds: Tp "), {"retime_speeds.yaml:", "time_law.knot_speeds", "one value"});
  expect_bad(replaced(base, "knot_speeds: v ", "knot_speeds: vv "), {"retime_speeds.yaml:", "time_law.knot_speeds", "no parameter", "did you mean 'v'"});
  // an element that is not a number
  expect_bad(replaced(base, first, "v: [0.5, speed, 0.5,"), {"retime_speeds.yaml:", "parameters.v[1]"});
  // a variant cannot set a list parameter to one number
  expect_bad(replaced(base, "\noptimize:", "\nvariants: {sweep: {v: [1, 2]}}\noptimize:"), {"retime_speeds.yaml:", "variants.sweep.v", "list parameter"});
}

TEST(TimeLawKnotSpeeds, TheExampleEndsAtTheLawsEndAndBadInputIsOneLocatedError) {
  const auto p = io::load_problem(kSpeedsExample);
  // K = 128, Δτ = 2/128: 126 inner parts at ṡ = 0.5 (2Δτ/1 s each) and two end parts from/to
  // rest (2Δτ/0.5 s each)
  const double dtau = 2.0 / 128;
  EXPECT_NEAR(p->integrator.t1, 126 * 2 * dtau + 2 * (2 * dtau / 0.5), 1e-12);
  // `t1: end` is the law's own end, the last knot to the bit, and has no text of its own: its
  // derivative in the parameters is the law's (Problem::t1_is_law_end, symbolic/sensitivity.cpp)
  ASSERT_TRUE(p->time_law);
  EXPECT_TRUE(p->t1_is_law_end);
  EXPECT_EQ(p->integrator.t1, p->time_law->end_time());
  EXPECT_EQ(p->integrator.t1, p->time_law_knots.back());
  EXPECT_TRUE(p->texts.t1.empty()) << p->texts.t1;
  // t1: end on the segments form: Σ d_i
  const std::string sixteen = "t1: d1 + d2 + d3 + d4 + d5 + d6 + d7 + d8 + d9 + d10 + d11 + d12 + d13 + d14 + d15 + d16";
  const auto seg = io::parse_problem(replaced(example_text(), sixteen, "t1: end"), "retime.yaml");
  ASSERT_TRUE(seg->time_law);
  EXPECT_TRUE(seg->t1_is_law_end);
  EXPECT_NEAR(seg->integrator.t1, 2.0, 1e-12);
  EXPECT_EQ(seg->integrator.t1, seg->time_law->end_time());
  EXPECT_TRUE(seg->texts.t1.empty()) << seg->texts.t1;
  // t1 written as a text keeps it (its derivative from the text), and is not the law's end
  const auto written = io::parse_problem(example_text(), "retime.yaml");
  EXPECT_FALSE(written->t1_is_law_end);
  EXPECT_EQ(written->texts.t1, sixteen.substr(4));
  const std::string base = test::read_file(kSpeedsExample);
  const std::string src = "retime_speeds.yaml";
  auto expect_bad = [&](const std::string& yaml, const std::vector<std::string>& needles) {
    test::expect_error_mentioning([&] { (void)io::parse_problem(yaml, src); }, needles);
  };
  const std::string speeds = "knot_speeds: [v1, v2,";
  expect_bad(replaced(base, speeds, "knot_speeds: [v1, 0,"), {"retime_speeds.yaml:", "time_law.knot_speeds[1]", "> 0"});
  expect_bad(replaced(base, speeds, "knot_speeds: [v1, -0.5,"), {"retime_speeds.yaml:", "time_law.knot_speeds[1]", "> 0"});
  expect_bad(replaced(base, "task_duration: Tp", "task_duration: Tp\n  segments: [1, 1]"),
             {"retime_speeds.yaml:", "knot_speeds", "exclude"});
  // t1: end without a time law
  std::string no_law = test::read_file(kSpeedsExample);
  no_law = replaced(no_law, "time_law:\n  task_duration: Tp\n", "");
  no_law = no_law.substr(0, no_law.find("  knot_speeds:")) + no_law.substr(no_law.find("\n", no_law.find("  knot_speeds:")) + 1);
  test::expect_error_mentioning([&] { (void)io::parse_problem(no_law, src); }, {"retime_speeds.yaml:", "integrator.t1", "time_law"});
}

TEST(TimeLawScenario, TheExampleBuildsAndItsFunctionsAreRetimed) {
  const auto p = io::load_problem(kExample);
  ASSERT_EQ(p->constraints.size(), 2);
  // end of the law: 16 × 0.125 = 2 s; the first row's target is x(E)(τ = s(t)) with exact rates
  const auto spec = io::load_scenario(kExample);
  EXPECT_TRUE(static_cast<bool>(spec.time_law));
}

TEST(TimeLawScenario, BadInputIsOneLocatedError) {
  const std::string base = example_text();
  const std::string src = "retime.yaml";
  auto expect_bad = [&](const std::string& yaml, const std::vector<std::string>& needles) {
    test::expect_error_mentioning([&] { (void)io::parse_problem(yaml, src); }, needles);
  };
  const std::string segs = "segments: [d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12, d13, d14, d15, d16]";
  expect_bad(replaced(base, segs, "segments: [d1, -0.1, d3]"), {"retime.yaml:", "time_law.segments[1]", "> 0"});
  expect_bad(replaced(base, segs, "segments: []"), {"retime.yaml:", "time_law.segments", "empty"});
  expect_bad(replaced(base, segs, "segments: 0.5"), {"retime.yaml:", "time_law.segments", "list"});
  expect_bad(replaced(base, "task_duration: Tp", "task_duration: 0"), {"retime.yaml:", "time_law.task_duration", "> 0"});
  expect_bad(replaced(base, "task_duration: Tp", "task_duration: Tp\n  knots: 3"),
             {"retime.yaml:", "time_law.knots", "unknown key"});
  expect_bad(replaced(base, "task_duration: Tp\n", ""), {"retime.yaml:", "time_law.task_duration", "missing"});
  // nothing to retime: the circle's functions made constant
  expect_bad(replaced(replaced(base, "cx + R*cos(2*pi*t/Tp)", "cx + R"), "cy + R*sin(2*pi*t/Tp)", "cy"),
             {"retime.yaml:", "time_law", "nothing to retime"});
  // an expression constraint in t is refused with a hint (not silently left on real time)
  expect_bad(replaced(base, "- {name: ey, kind: point_coordinate, point: E, axis: y, function: cy + R*sin(2*pi*t/Tp)}",
                      "- {name: ey, expression: y(E) - cy - R*sin(2*pi*t/Tp)}"),
             {"retime.yaml:", "expression", "function:"});
  // the line of the error is the time law's
  try {
    (void)io::parse_problem(replaced(base, segs, "segments: [d1, 0, d3]"), src);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string w = e.what();
    EXPECT_EQ(w.find('\n'), std::string::npos) << w;
    const auto line = std::count(base.begin(), base.begin() + static_cast<long>(base.find(segs)), '\n') + 1;
    EXPECT_NE(w.find("retime.yaml:" + std::to_string(line) + ":"), std::string::npos) << w;
  }
}

namespace {
int run_cli(const std::string& args, std::string* err = nullptr) {
  const fs::path dir = fs::temp_directory_path() / ("time_law_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string cmd = std::string("'") + REFDYN_CLI + "' " + args + " >'" + (dir / "out").string() + "' 2>'" +
                          (dir / "err").string() + "' </dev/null";
  const int status = std::system(cmd.c_str());
  if (err) *err = test::read_file((dir / "err").string());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}
}  // namespace

TEST(TimeLawScenario, CliPlansAndGeneratesTheExampleAndRefusesBadInputWithExit2) {
  const fs::path out = fs::temp_directory_path() / ("time_law_cli_" + std::to_string(::getpid()));
  fs::remove_all(out);
  EXPECT_EQ(run_cli("plan '" + kExample + "' -o '" + (out / "plan").string() + "'"), 0);
  EXPECT_TRUE(fs::exists(out / "plan" / "feasibility.json"));
  EXPECT_EQ(run_cli("generate '" + kExample + "' -o '" + (out / "gen").string() + "'"), 0);
  const std::string c = test::read_file((out / "gen" / "reference_dynamics.c").string());
  EXPECT_NE(c.find("d16"), std::string::npos);  // the durations stay parameters of the generated code
  const fs::path bad = out / "bad.yaml";
  std::ofstream(bad) << replaced(example_text(), "segments: [d1, d2,", "segments: [d1, -1,");
  std::string err;
  EXPECT_EQ(run_cli("plan '" + bad.string() + "' -o '" + (out / "bad").string() + "'", &err), 2);
  EXPECT_FALSE(fs::exists(out / "bad"));
  EXPECT_NE(err.find("time_law.segments[1]"), std::string::npos) << err;
  fs::remove_all(out);
}

// ---- the independent time-optimal reference (topp_reference.hpp) ----

TEST(ToppReference, DoubleIntegratorBangBangAndSpeedLimitedClosedForms) {
  // one joint q = θ over Δ = 2: a = 1, b = c = 0. |τ| ≤ 3: T = 2√(Δ/a_max); with |q̇| ≤ 1 too:
  // accelerate, cruise, decelerate: T = Δ/v + v/a.
  const double inf = std::numeric_limits<double>::infinity();
  test::PathDynamics p;
  p.theta_end = 2.0;
  for (int i = 0; i <= 1000; ++i) {
    p.a.push_back(Eigen::VectorXd::Ones(1));
    p.b.push_back(Eigen::VectorXd::Zero(1));
    p.c.push_back(Eigen::VectorXd::Zero(1));
    p.dq.push_back(Eigen::VectorXd::Ones(1));
  }
  EXPECT_NEAR(test::topp_min_time(p, {Eigen::VectorXd::Constant(1, 3.0), Eigen::VectorXd::Constant(1, inf)}),
              2 * std::sqrt(2.0 / 3.0), 1e-12);
  EXPECT_NEAR(test::topp_min_time(p, {Eigen::VectorXd::Constant(1, 3.0), Eigen::VectorXd::Constant(1, 1.0)}),
              2.0 / 1.0 + 1.0 / 3.0, 1e-5);
  // a point path with only speed limits (a huge effort limit): T → Δ/v. On the grid the first
  // and the last step start and end at rest (x = 0), each taking 2h/v instead of h/v: the
  // discretization's O(h) error, here exactly 2h/v with h = Δ/N.
  const double h = 2.0 / 1000;
  EXPECT_NEAR(test::topp_min_time(p, {Eigen::VectorXd::Constant(1, 1e6), Eigen::VectorXd::Constant(1, 0.5)}),
              2.0 / 0.5 + 2 * h / 0.5, 1e-5);
}

TEST(ToppReference, HandWrittenTwoLinkDynamicsEqualRefdynsInverseDynamics) {
  const auto p = io::load_problem(kExample);
  Data data(p->model);
  const test::TwoLinkArm arm;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-2, 2);
  for (int k = 0; k < 20; ++k) {
    Eigen::VectorXd q(2), qd(2), qdd(2);
    q << U(rng), U(rng);
    qd << U(rng), U(rng);
    qdd << U(rng), U(rng);
    const Eigen::VectorXd tau = inverse_dynamics(p->model, data, q, qd, qdd);
    const Eigen::Vector2d ref = arm.inverse_dynamics(q, qd, qdd);
    EXPECT_NEAR((tau - ref).norm(), 0.0, 1e-11 * (1 + ref.norm()));
  }
  // the closed-form inverse kinematics puts E on the circle with the θ-derivatives it claims
  const test::Circle c;
  for (int k = 0; k <= 12; ++k) {
    const double th = 2 * std::numbers::pi * k / 12;
    Eigen::Vector2d q, dq, ddq, qp, dqp, ddqp, qm, dqm, ddqm;
    test::circle_ik(arm, c, th, q, dq, ddq);
    const double ex = arm.L1 * std::cos(q[0]) + arm.L2 * std::cos(q[0] + q[1]);
    const double ey = arm.L1 * std::sin(q[0]) + arm.L2 * std::sin(q[0] + q[1]);
    EXPECT_NEAR(ex, c.cx + c.R * std::cos(th), 1e-14);
    EXPECT_NEAR(ey, c.cy + c.R * std::sin(th), 1e-14);
    const double h = 1e-5;
    test::circle_ik(arm, c, th + h, qp, dqp, ddqp);
    test::circle_ik(arm, c, th - h, qm, dqm, ddqm);
    EXPECT_NEAR((dq - (qp - qm) / (2 * h)).norm(), 0.0, 1e-8);
    EXPECT_NEAR((ddq - (dqp - dqm) / (2 * h)).norm(), 0.0, 1e-8);
  }
}

TEST(ToppReference, MinimumTimesOfThe2RCircleConvergeUnderGridRefinement) {
  // The T* the retiming optimization is compared with (examples/planar_2r_circle/retime.yaml:
  // effort limits 18 and 5 N m; with vmax = 2.5 rad/s on both joints for the second case).
  const double inf = std::numeric_limits<double>::infinity();
  const test::TwoLinkArm arm;
  const test::Circle c;
  const test::ToppLimits effort{Eigen::Vector2d(18, 5), Eigen::Vector2d(inf, inf)};
  const test::ToppLimits both{Eigen::Vector2d(18, 5), Eigen::Vector2d(2.5, 2.5)};
  const double e1 = test::topp_min_time(arm, c, effort, 10000), e2 = test::topp_min_time(arm, c, effort, 40000);
  const double b1 = test::topp_min_time(arm, c, both, 10000), b2 = test::topp_min_time(arm, c, both, 40000);
  std::printf("T* effort limits: %.6f s (N = 10000), %.6f s (N = 40000)\n", e1, e2);
  std::printf("T* effort + speed limits: %.6f s (N = 10000), %.6f s (N = 40000)\n", b1, b2);
  EXPECT_NEAR(e1, e2, 1e-4 * e2);
  EXPECT_NEAR(b1, b2, 1e-4 * b2);
  EXPECT_LT(e2, 1.0);   // clearly below the 2 s of the original example
  EXPECT_GT(b2, e2 * 1.1);  // the speed limits are active
  // no admissible traversal when the effort limit is below the static gravity torque (≈ 14 N m)
  EXPECT_EQ(test::topp_min_time(arm, c, {Eigen::Vector2d(10, 5), Eigen::Vector2d(inf, inf)}, 2000), inf);
}

namespace {
/// Plans the example with uneven parts (seeded) and integrator step `step`; the worst
/// difference between the plan's required efforts and the hand-written arm's along the exact
/// retimed path, over the samples away from the end of the motion.
double worst_effort_difference(const std::string& step, int* samples) {
  std::string yaml = replaced(example_text(), "step: 1e-3", "step: " + step);
  std::vector<Number> d;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.08, 0.25);
  for (int i = 1; i <= 16; ++i) {
    const double v = std::round(U(rng) * 1000) / 1000;
    d.emplace_back(v);
    yaml = replaced(yaml, "  d" + std::to_string(i) + ": Tp/16", "  d" + std::to_string(i) + ": " + fmt(v));
  }
  const fs::path out = fs::temp_directory_path() / ("time_law_e2e_" + std::to_string(::getpid()));
  fs::remove_all(out);
  fs::create_directories(out);
  std::ofstream(out / "uneven.yaml") << yaml;
  EXPECT_EQ(run_cli("plan '" + (out / "uneven.yaml").string() + "' -o '" + (out / "plan").string() + "'"), 0);
  std::ifstream csv(out / "plan" / "plan.csv");
  std::string line;
  std::getline(csv, line);
  const TimeLaw law(2.0, d);
  const test::TwoLinkArm arm;
  const test::Circle c;
  const double k = 2 * std::numbers::pi / 2.0;
  double worst = 0;
  *samples = 0;
  while (std::getline(csv, line)) {
    std::vector<double> v;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) v.push_back(std::stod(cell));
    const double t = v[0];
    if (t > law.end_time() - 1e-2) continue;
    const TimeLawValue s = law.eval(t);
    Eigen::Vector2d q, dq, ddq;
    test::circle_ik(arm, c, k * s.s, q, dq, ddq);
    const double th_d = k * s.ds, th_dd = k * s.dds;
    const Eigen::Vector2d tau = arm.inverse_dynamics(q, dq * th_d, dq * th_dd + ddq * th_d * th_d);
    worst = std::max({worst, std::abs(v[16] - tau[0]), std::abs(v[17] - tau[1])});  // required_q1, required_q2
    ++*samples;
  }
  fs::remove_all(out);
  return worst;
}
}  // namespace

TEST(TimeLawScenario, PlannedEffortsOfTheRetimedCircleConvergeToTheHandWrittenDynamics) {
  // End to end: the example with uneven parts planned by refdyn; the required efforts against
  // τ = M q̈ + C q̇ + g of the hand-written arm along q(θ), θ = 2π s(t)/Tp, θ̇ = 2π ṡ/Tp,
  // θ̈ = 2π s̈/Tp (s from TimeLaw, q from the closed-form IK): the chain rule through the whole
  // engine (a wrong or missing term, e.g. f′s̈, is an O(1) error that no step size removes).
  // s̈ jumps at the knots (s is C¹). When RK4 steps straddled them a step that contained a knot
  // was only first-order accurate there: the plan's residual (|Φ| ~ 2e-5 m at step 1e-3 s) was
  // corrected by Baumgarte's 2αΦ̇ + β²Φ into an effort error of 0.37 N m at 1e-3 s and 0.037 N m
  // at 1e-4 s (peak efforts ~50 N m). The knots are now integrator breakpoints (RK4 steps land on
  // them, integrators.hpp Rk4Grid): RK4 is fourth order on every part, and the difference is at
  // the level of the CSV's digits at both steps.
  int n1 = 0, n2 = 0;
  const double w1 = worst_effort_difference("1e-3", &n1), w2 = worst_effort_difference("1e-4", &n2);
  std::printf("retimed circle, uneven parts: worst |required − hand τ| = %.3g N m (step 1e-3 s, %d samples), "
              "%.3g N m (step 1e-4 s, %d samples)\n", w1, n1, w2, n2);
  EXPECT_GT(n1, 1000);
  EXPECT_GT(n2, 10000);
  EXPECT_LT(w1, 1e-3);  // 0.37 N m with the knots inside RK4 steps
  EXPECT_LT(w2, 1e-3);
}

// The knot-speed law against the true time-optimal traversal, found by refdyn optimize:
// tests/phase_plane_test.cpp.

// TimeLaw::jet and duration_jet (what the sensitivities evaluate natively): ∂(s, ṡ, s̈)/∂θ at a
// fixed t, for both forms, against central differences of laws rebuilt with one number moved
// (h = 1e-6 relative, t kept inside its part); the start knot's share through knot_derivatives.
// Budget: the laws are smooth in θ inside a part (away from the slope limiter's switch, where the
// dual route takes the branch eval takes): truncation ~h², rounding ~1e-16/(1e-6 d) for durations d ≥ 0.02; tolerance 1e-6.
TEST(TimeLawJet, DerivativesInTheLawsNumbersMatchCentralDifferences) {
  std::mt19937 rng(43);
  for (const TimeLawForm form : {TimeLawForm::knot_speeds, TimeLawForm::segments}) {
    SCOPED_TRACE(form == TimeLawForm::knot_speeds ? "knot_speeds" : "segments");
    const int K = 9;
    std::vector<Number> values =
        form == TimeLawForm::knot_speeds ? random_speeds(rng, K - 1) : random_segments(rng, K);
    const double Tp = 1.7;
    const TimeLaw law(form, Number(Tp), values);
    const std::vector<std::vector<double>> dknots = law.knot_derivatives();
    std::uniform_real_distribution<double> U(0, 1);
    double worst = 0;
    for (int sample = 0; sample < 60; ++sample) {
      const int i = 1 + static_cast<int>(U(rng) * K) % K;
      const double a = law.knots()[static_cast<size_t>(i) - 1], b = law.knots()[static_cast<size_t>(i)];
      const double t = a + (b - a) * (0.2 + 0.6 * U(rng));
      const TimeLaw::Jet j = law.jet(t);
      ASSERT_EQ(j.knot, i - 1);
      const TimeLawValue v = law.eval(t);
      EXPECT_EQ(j.value.s, v.s);
      EXPECT_EQ(j.value.dds, v.dds);
      for (size_t q = 0; q <= values.size(); ++q) {  // θ_q
        auto moved = [&](double e) {
          std::vector<Number> w = values;
          double T = Tp;
          if (q == 0) T += e;
          else w[q - 1].value += e;
          const TimeLawValue r = TimeLaw(form, Number(T), w).eval(t);
          return std::array<double, 3>{r.s, r.ds, r.dds};
        };
        const double e = 1e-6 * (q == 0 ? Tp : values[q - 1].value);
        const std::array<double, 3> up = moved(e), down = moved(-e);
        for (int k = 0; k < 3; ++k) {
          double an = j.dknot[static_cast<size_t>(k)] * dknots[static_cast<size_t>(j.knot)][q];
          for (int l = 0; l < 4; ++l)
            if (j.theta[static_cast<size_t>(l)] == static_cast<int>(q)) an += j.d[static_cast<size_t>(k)][static_cast<size_t>(l)];
          const double fd = (up[static_cast<size_t>(k)] - down[static_cast<size_t>(k)]) / (2 * e);
          worst = std::max(worst, std::abs(an - fd) / std::max(1.0, std::abs(fd)));
          EXPECT_NEAR(an, fd, 1e-6 * std::max(1.0, std::abs(fd))) << "k " << k << " theta " << q << " t " << t;
        }
      }
    }
    // the knots: ∂t_i/∂θ by the sums of duration_jet
    for (size_t q = 0; q <= values.size(); ++q) {
      const double e = 1e-6 * (q == 0 ? Tp : values[q - 1].value);
      auto knots = [&](double d) {
        std::vector<Number> w = values;
        double T = Tp;
        if (q == 0) T += d;
        else w[q - 1].value += d;
        return TimeLaw(form, Number(T), w).knots();
      };
      const std::vector<double> up = knots(e), down = knots(-e);
      for (size_t i = 0; i < up.size(); ++i)
        EXPECT_NEAR(dknots[i][q], (up[i] - down[i]) / (2 * e), 1e-6 * std::max(1.0, std::abs(dknots[i][q])));
    }
    std::printf("time law jet (%s): worst relative difference to central differences %.2e\n",
                form == TimeLawForm::knot_speeds ? "knot_speeds" : "segments", worst);
  }
}

// LocalTimeLawForm: under it a retimed function's symbolic form is f of the law's local form in
// four symbols, of the same size for any K (the sensitivities bind them); without it the
// piecewise text of every knot.
TEST(TimeLawJet, TheLocalFormHasTheSameSizeForAnyK) {
  std::vector<size_t> sizes;
  for (int K : {4, 64, 512}) {
    const auto law = std::make_shared<const TimeLaw>(TimeLawForm::knot_speeds, Number(2.0),
                                                     std::vector<Number>(static_cast<size_t>(K) - 1, Number(1.0)));
    const TimeFunctionPtr f = time_law_function(expression_time_function("0.6 + 0.15*cos(2*pi*t/2)"), law);
    {
      const LocalTimeLawForm local;
      const std::optional<SymbolicForm> form = f->symbolic();
      ASSERT_TRUE(form);
      sizes.push_back(form->rows.at(0).size());
      for (const char* name : kTimeLawSymbols) EXPECT_TRUE(form->parameters.count(name)) << name;
      EXPECT_EQ(form->rows[0].find("if("), std::string::npos);
    }
    EXPECT_NE(f->symbolic()->rows.at(0).find("if("), std::string::npos);  // outside: the piecewise text
  }
  EXPECT_EQ(sizes[0], sizes[1]);
  EXPECT_EQ(sizes[1], sizes[2]);
}
