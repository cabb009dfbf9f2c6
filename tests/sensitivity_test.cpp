// Forward sensitivities of plans (symbolic/sensitivity.hpp) against central differences of
// whole plans: the paper's manipulator (a drive duration, the height law, a model parameter that
// a derived parameter and the initial height follow), the waiter tray (acceleration-level row,
// the swing and its period) and the unicycle (nonholonomic, material and programmed rows, the
// speed in the initial velocity too). Metrics and the state at samples, relative 1e-5.
#include "refdyn/common/text.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/metrics.hpp"
#include "refdyn/symbolic/sensitivity.hpp"
#include "test_support.hpp"
#include "topp_reference.hpp"

#include <gtest/gtest.h>

#include <array>

#include <cmath>
#include <limits>
#include <fstream>
#include <sstream>

namespace refdyn {
namespace {

std::string source(const std::string& rel) {
  std::ifstream f(std::string(REFDYN_SOURCE_DIR) + "/" + rel);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

struct Planned {
  std::unique_ptr<Problem> problem;
  Plan plan;
  std::vector<Metric> metrics;
};

Planned plan_with(const ScenarioSpec& spec, const std::string& name = "", double value = 0) {
  ScenarioSpec s = spec;
  if (!name.empty()) {
    Quantity q;
    q.value = value;
    s.parameter_values[name] = q;
  }
  Planned p;
  p.problem = build_problem(s);
  p.plan = plan_problem(*p.problem, *p.problem->make_planner());
  EXPECT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  p.metrics = plan_metrics(p.problem->model, p.plan, p.problem->residual_from);
  return p;
}

/// The sensitivities of every metric and of the state at a few samples against central
/// differences with a relative step `rel`.
/// A derivative passes when |analytic − differences| ≤ tol · max(|differences|, floor · |J| / |p|):
/// relative to itself, or, for a small coupling, to the metric's own scale |J|/|p| (a normalized
/// sensitivity (p/J) dJ/dp within tol·floor). The state, and the metrics that are a state
/// component at a sample (final_q, final_qd, q_min, q_max, peak_speed), are allowed the
/// differences' own rounding error besides (differences_rounding): where the true derivative is
/// ~0 (a sample before the knot a knot speed moves; a state that a parameter moves only through
/// the integration error) the differences are rounding noise, not a derivative.
enum Check { kMetrics = 1, kStates = 2, kBoth = 3 };

/// The rounding error of the fourth-order central differences of the plan's state at each sample,
/// for a step h of the parameter. Each plan's state at sample j carries rounding of a few ulps of
/// the plan's scale up to there, S_j = max over samples k ≤ j and components i of
/// |x_i(t_k)| + t_k |ẋ_i(t_k)|: its values are rounded (eps |x|), and so are the times it is
/// integrated on (a time law's knots are sums of the parts' durations, the steps land on them, the
/// law is evaluated at t − t_knot), and a time off by eps·t moves the state by ẋ·eps·t; an error
/// made at an earlier sample is carried on by the stable but slowly forgetting error dynamics
/// (Baumgarte), hence the maximum over k ≤ j, and across components by the dynamics, hence over
/// i. The four plans round independently (their grids differ), and (−f(2h) + 8 f(h) − 8 f(−h) +
/// f(−2h))/12h adds their errors with weights of total 18/12: the differences' error is at most
/// 1.5 · c · eps · S_j / h with c · eps · S_j a plan's own rounding error. c = 4: measured, the
/// differences of states whose derivative is ~0 (≤ 1e-9) reach 2.8 · 1.5 eps S_j/h (every 7th
/// sample of the 128- and 512-part circles below, v1, v64, v127, v300). There h ~ 1e-5 and S_j
/// grows from ~1.4 at the start to ~160 at the 512-part circle's end (its last parts stop the arm,
/// |q̈| ~ 100): 2e-10 … 1.5e-8, in columns whose largest entries are ~1; the analytic values
/// where the floor decides are ~1e-14 (0 where the plans agree to the bit).
std::vector<double> differences_rounding(const Plan& plan, double h) {
  constexpr double eps = std::numeric_limits<double>::epsilon(), c = 4;
  std::vector<double> out(plan.t.size());
  double S = 0;
  for (size_t k = 0; k < plan.t.size(); ++k) {
    const Eigen::ArrayXd x = plan.x[k].array().abs();
    Eigen::ArrayXd rate = Eigen::ArrayXd::Zero(x.size());  // |ẋ|: the larger one-sided difference quotient
    if (k > 0) rate = rate.max(((plan.x[k] - plan.x[k - 1]) / (plan.t[k] - plan.t[k - 1])).array().abs());
    if (k + 1 < plan.t.size()) rate = rate.max(((plan.x[k + 1] - plan.x[k]) / (plan.t[k + 1] - plan.t[k])).array().abs());
    S = std::max(S, (x + std::abs(plan.t[k]) * rate).maxCoeff());
    out[k] = 1.5 * c * eps * S / h;
  }
  return out;
}
void check_against_differences(const std::string& yaml, const std::vector<std::string>& parameters,
                               double rel = 1e-5, double floor = 1e-3, int what = kBoth, double tol = 1e-5) {
  const ScenarioSpec spec = io::parse_scenario(yaml, "sensitivity_test.yaml");
  const Planned base = plan_with(spec);
  SensitivityOptions opt;
  opt.parameters = parameters;
  const PlanSensitivity s = plan_sensitivity(*base.problem, base.plan, opt);
  ASSERT_EQ(s.t.size(), base.plan.t.size());
  const Eigen::MatrixXd G = metric_gradients(*base.problem, base.plan, s, base.metrics);
  for (size_t k = 0; k < parameters.size(); ++k) {
    const std::string& p = parameters[k];
    const double v = base.problem->parameters.at(p), h = rel * std::max(std::abs(v), 1e-3);
    // Fourth-order central differences, (−f(2h) + 8 f(h) − 8 f(−h) + f(−2h)) / 12h: the
    // friction's stiff nonlinearity makes the second-order ones too coarse for small couplings.
    const Planned up = plan_with(spec, p, v + h), down = plan_with(spec, p, v - h);
    const Planned up2 = plan_with(spec, p, v + 2 * h), down2 = plan_with(spec, p, v - 2 * h);
    ASSERT_EQ(up.metrics.size(), base.metrics.size());
    auto diff = [&](auto get) -> decltype(get(up)) {  // a value, not an expression of temporaries
      return (8.0 * (get(up) - get(down)) - (get(up2) - get(down2))) / (12 * h);
    };
    const std::vector<double> rounding = differences_rounding(base.plan, h);
    // where the allowed error holds only with the differences' rounding added: printed (a real
    // mismatch must not hide there)
    auto by_rounding = [&](const std::string& what, double err, double relative, long sample) {
      if (err > relative)
        std::printf("  rounding floor decided: %s at t = %.6g: |analytic - differences| %.3g > relative bound %.3g, "
                    "the differences' rounding %.3g added\n", what.c_str(), base.plan.t[static_cast<size_t>(sample)],
                    err, relative, rounding[static_cast<size_t>(sample)]);
    };
    std::map<MetricKind, double> largest;  // per kind: values far below it are rounding noise
    for (const Metric& m : base.metrics) largest[m.kind] = std::max(largest[m.kind], std::abs(m.value));
    for (size_t i = 0; i < base.metrics.size() && (what & kMetrics); ++i) {
      const Metric& m = base.metrics[i];
      if (m.kind == MetricKind::MaxResidual) continue;  // rounding-level values
      if (std::abs(m.value) < 1e-7 * largest[m.kind]) continue;
      bool moved = false;  // the argmax moved to another sample: not differentiable there
      for (const Planned* o : {&up, &down, &up2, &down2}) moved = moved || o->metrics[i].sample != m.sample;
      if (moved) continue;
      const double fd = diff([&](const Planned& o) { return o.metrics[i].value; });
      const double scale = std::max({std::abs(fd), floor * std::abs(m.value) / std::max(std::abs(v), 1e-3), 1e-9});
      const bool state = m.kind == MetricKind::FinalQ || m.kind == MetricKind::FinalQd || m.kind == MetricKind::QMin ||
                         m.kind == MetricKind::QMax || m.kind == MetricKind::PeakSpeed;
      const double g = G(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k));
      const double allowed = tol * scale + (state ? rounding[static_cast<size_t>(m.sample)] : 0.0);
      if (state) by_rounding("d " + m.name + "/d" + p, std::abs(g - fd), tol * scale, m.sample);
      EXPECT_NEAR(g, fd, allowed) << "d " << m.name << " / d " << p << " (value " << m.value << ")";
    }
    // the state at three samples (off the symmetric instants of the tasks, where a joint speed
    // crosses zero: there the friction's |q̇| has a kink in time) and at the end
    const size_t K = base.plan.t.size();
    for (size_t j : {K * 3 / 10, K * 11 / 20, K * 9 / 10, K - 1}) {
      if (!(what & kStates)) break;
      const Eigen::VectorXd fd = diff([&](const Planned& o) -> Eigen::VectorXd { return o.plan.x[j]; });
      const Eigen::VectorXd an = s.dx[j].col(static_cast<Eigen::Index>(k));
      const double scale = std::max(fd.cwiseAbs().maxCoeff(), 1e-6), err = (an - fd).cwiseAbs().maxCoeff();
      by_rounding("dx/d" + p, err, tol * scale, static_cast<long>(j));
      EXPECT_LE(err, tol * scale + rounding[j])
          << "dx/d" << p << " at t = " << base.plan.t[j] << "\nanalytic " << an.transpose() << "\ndifferences "
          << fd.transpose();
    }
  }
}

std::string paper_with_duration() {
  std::string y = source("examples/paper/paper.yaml");
  y = replace(y, "  Tz: 5 ", "  Tz: 5\n  Td: 5 ");
  y = replace(y, "rise: 2*pi, duration: 5", "rise: 2*pi, duration: Td");
  // The plan ends at 4.5 s, in motion: at rest (t = 5 s) the slider's LuGre friction sticks
  // (Stribeck speed 1 mm/s) and its state's differences converge only below a relative step of
  // 1e-6, where rounding takes over elsewhere.
  y = replace(y, "t0: 0, t1: 5,", "t0: 0, t1: 4.5,");
  return y;
}

TEST(Sensitivity, PaperDriveDurationAndHeightLawAgreeWithCentralDifferences) {
  // The slider's LuGre friction (Stribeck speed 1 mm/s) makes this plan rough at the 1e-4
  // level in the parameters: differences of the effort integral in Td scatter by ±1e-4 over
  // steps 1e-3 … 1e-6 (44.1255 … 44.1310) while the sensitivity is 44.12999778613 in every
  // run. So the metrics are compared as normalized sensitivities (floor 1: within 1e-5 of
  // |J|/|p|), with a relative step of 1e-4. The friction states (bristle deflections) need a
  // step of 1e-6 to converge: the states at the samples are compared so, within 1e-5.
  check_against_differences(paper_with_duration(), {"Td", "dz", "Tz"}, 1e-4, 1.0, kMetrics);
  check_against_differences(paper_with_duration(), {"Td", "dz", "Tz"}, 1e-6, 1.0, kStates);
}

TEST(Sensitivity, PaperModelParameterFollowedByADerivedParameterAgrees) {
  // h1 sets the column's height (model), and z0 = h1 + … the height law's base: both move.
  check_against_differences(paper_with_duration(), {"h1"});
}

TEST(Sensitivity, WaiterTraySwingAndPeriodAgree) {
  check_against_differences(source("examples/waiter_tray/waiter_tray.yaml"), {"swing", "T"});
}

TEST(Sensitivity, NonholonomicUnicycleSpeedAndDampingAgree) {
  check_against_differences(source("examples/unicycle/unicycle.yaml"), {"v0", "c", "omega"});
}

TEST(Sensitivity, CircleRadiusThroughTheProjectedInitialStateAgrees) {
  // consistency: project, a fully prescribed path; R moves the start (q10, q20 from R) and v0.
  check_against_differences(source("examples/planar_2r_circle/planar_2r_circle.yaml"), {"R", "Tp"});
}

TEST(Sensitivity, FinalTimeWrittenWithAParameterMovesEverySample) {
  std::string y = source("examples/waiter_tray/waiter_tray.yaml");
  // T = 2.00025: t1 = 4.0005 s lies mid-way between two multiples of the step, so the
  // differences (t1 ± 4e-5 s) keep the number of RK4 steps, which the derivative holds.
  y = replace(y, "t0: 0, t1: 4}", "t0: 0, t1: 2*T}");
  y = replace(y, "T: 2.0 ", "T: 2.00025 ");
  check_against_differences(y, {"T"});
}

// The two routes to each RK4 stage's q̈, ż and λ: the plan's stored stages (plan.stages, the
// fast route) and evaluating the reference dynamics again (a plan without them): the same
// sensitivities (bit for bit here: the same stage states and the same arithmetic).
TEST(Sensitivity, StoredStagesGiveWhatEvaluatingTheDynamicsGives) {
  const Planned p = plan_with(io::parse_scenario(paper_with_duration(), "p.yaml"));
  ASSERT_GT(p.plan.stages.extra_size, 0);
  ASSERT_EQ(p.plan.stages.extra.size(), static_cast<size_t>(p.plan.stages.steps) * 4 * p.plan.stages.extra_size);
  SensitivityOptions o;
  o.parameters = {"Td", "dz"};
  (void)plan_sensitivity(*p.problem, p.plan, o);  // compiles the tapes (not timed below)
  const PlanSensitivity fast = plan_sensitivity(*p.problem, p.plan, o);
  Plan without = p.plan;
  without.stages.extra.clear();
  without.stages.extra_size = 0;
  const PlanSensitivity slow = plan_sensitivity(*p.problem, without, o);
  ASSERT_EQ(fast.t.size(), slow.t.size());
  ASSERT_EQ(fast.t.size(), p.plan.t.size());
  double worst = 0;
  for (size_t k = 0; k < fast.t.size(); ++k) {
    const double scale = 1 + slow.dx[k].cwiseAbs().maxCoeff();
    worst = std::max(worst, (fast.dx[k] - slow.dx[k]).cwiseAbs().maxCoeff() / scale);
    worst = std::max(worst, (fast.deffort[k] - slow.deffort[k]).cwiseAbs().maxCoeff() / (1 + slow.deffort[k].cwiseAbs().maxCoeff()));
  }
  std::printf("stored stages against evaluated dynamics: worst relative difference %.3g over %zu samples (%.3f s vs %.3f s)\n",
              worst, fast.t.size(), fast.seconds, slow.seconds);
  EXPECT_LT(worst, 1e-9);
}

// Under a time law the knots move with the knot speeds, and s̈ jumps there: the derivative of
// the state gets the jump term (f⁻ − f⁺) ∂t_k/∂p at every knot. A rotor turned through Θ by
// q = Θ s(t)/Tp on a 4-part knot-speed law has a closed form: q(t) = Θ s(t)/Tp, q̇ = Θ ṡ/Tp, with
// s piecewise quadratic through the knots; its derivative in v_j at the grid's moving sample
// times t_j(p) (t1 = end moves them) is differentiated here (central differences of the closed
// form, which is smooth in p) and compared with the plan's sensitivities.
/// The RK4 grid of a plan on a time law's parts (integrators.hpp, Rk4Grid: the knots are
/// breakpoints, t1: end): the steps of each part at `step`, and the time of grid point j for the
/// knots moved with the parameters (the counts kept: a small change moves the grid, it does not
/// divide it again). Every step end is a sample.
std::vector<long> part_steps(const std::vector<double>& knots, double step) {
  std::vector<long> n;
  for (size_t p = 0; p + 1 < knots.size(); ++p)
    n.push_back(std::max(1L, std::lround(std::ceil((knots[p + 1] - knots[p]) / step - 1e-9))));
  return n;
}
double grid_time(const std::vector<double>& knots, const std::vector<long>& n, size_t j) {
  for (size_t p = 0; p < n.size(); ++p) {
    const size_t np = static_cast<size_t>(n[p]);
    if (j == np) return knots[p + 1];
    if (j < np) return knots[p] + static_cast<double>(j) * (knots[p + 1] - knots[p]) / static_cast<double>(np);
    j -= np;
  }
  return knots.back();
}

/// A rotor turned by Θ in task time Tp on a time law (`law`: the time_law's form and list over
/// the parameters v1, v2, v3), rest to rest, ending at the law's end (`t1: end`).
std::string rotor_on_a_law(const std::string& law, double step = 1e-4) {
  return "name: rotor\nparameters:\n  Theta: 2\n  Tp: 1\n  v1: 0.9\n  v2: 1.6\n  v3: 1.1\n"
         "model:\n  gravity: [0, 0, -9.81]\n  links:\n"
         "    - {name: arm, joint: q1, parent: base, type: revolute, axis: [0, 0, 1], mass: 3, com: [0.25, 0, 0],\n"
         "       inertia: [0.001, 0.0625, 0.0625]}\n"
         "constraints:\n  - {name: turn, kind: joint_trajectory, joint: q1, function: Theta*t/Tp}\n"
         "time_law: {task_duration: Tp, " + law + "}\n"
         "partition:\n  independent: []\n"
         "baumgarte: {alpha: 100, beta: 50}\n"
         "initial:\n  q: {q1: 0}\n  qd: {q1: 0}\n"
         "integrator: {method: rk4, step: " + fmt(step) + ", t0: 0, t1: end}\n";
}

TEST(Sensitivity, UnderAKnotSpeedLawTheMovingKnotsAreFollowed) {
  const Planned base = plan_with(io::parse_scenario(rotor_on_a_law("knot_speeds: [v1, v2, v3]"), "rotor.yaml"));
  SensitivityOptions opt;
  opt.parameters = {"v1", "v2", "v3"};
  const PlanSensitivity s = plan_sensitivity(*base.problem, base.plan, opt);
  const size_t N = base.plan.t.size() - 1;  // steps (every step is a sample)
  const std::vector<long> counts = part_steps(base.problem->time_law_knots, 1e-4);
  // The closed form: the state at the j-th grid time (grid_time) of the law with speeds v.
  auto state = [&](const std::array<double, 3>& v3, size_t j) {
    const double Theta = 2, Tp = 1, dtau = Tp / 4;
    const double v[5] = {0, v3[0], v3[1], v3[2], 0};
    std::vector<double> knots(5, 0.0);
    for (size_t i = 0; i < 4; ++i) knots[i + 1] = knots[i] + 2 * dtau / (v[i] + v[i + 1]);
    const double t = grid_time(knots, counts, j);
    int i = 0;
    while (i < 3 && t >= knots[i + 1]) ++i;
    const double h = t - knots[i], a = (v[i + 1] * v[i + 1] - v[i] * v[i]) / (2 * dtau);
    const double sv = std::min(Tp, i * dtau + v[i] * h + 0.5 * a * h * h), ds = v[i] + a * h;
    return Eigen::Vector2d(Theta * sv / Tp, Theta * ds / Tp);
  };
  const std::array<double, 3> v0{0.9, 1.6, 1.1};
  double worst = 0, scale = 0;
  for (size_t j : {N / 5, N / 3, N / 2, 2 * N / 3, 9 * N / 10, N}) {
    for (int k = 0; k < 3; ++k) {
      std::array<double, 3> up = v0, down = v0;
      const double e = 1e-6;
      up[static_cast<size_t>(k)] += e;
      down[static_cast<size_t>(k)] -= e;
      const Eigen::Vector2d fd = (state(up, j) - state(down, j)) / (2 * e);
      const Eigen::Vector2d an = s.dx[j].col(k).head(2);
      worst = std::max(worst, (an - fd).cwiseAbs().maxCoeff());
      scale = std::max(scale, fd.cwiseAbs().maxCoeff());
    }
  }
  std::printf("rotor on a knot-speed law: worst |∂x/∂v − closed form| = %.3g (largest derivative %.3g)\n", worst, scale);
  // The metrics t_end and effort_energy = ∫ τ² dt = Σ_i (I Θ a_i/Tp)² δ_i (I = 0.25 kg m²: the
  // effort is I q̈, constant on each part), against the closed form's differences.
  auto energy = [](const std::array<double, 3>& v3) {
    const double Theta = 2, Tp = 1, dtau = Tp / 4, I = 0.25;
    const double v[5] = {0, v3[0], v3[1], v3[2], 0};
    double E = 0, T = 0;
    for (int i = 0; i < 4; ++i) {
      const double d = 2 * dtau / (v[i] + v[i + 1]), a = (v[i + 1] * v[i + 1] - v[i] * v[i]) / (2 * dtau);
      E += std::pow(I * Theta * a / Tp, 2) * d;
      T += d;
    }
    return Eigen::Vector2d(T, E);
  };
  const Eigen::MatrixXd G = metric_gradients(*base.problem, base.plan, s, base.metrics);
  long it_end = -1, it_energy = -1;
  for (size_t i = 0; i < base.metrics.size(); ++i) {
    if (base.metrics[i].name == "t_end") it_end = static_cast<long>(i);
    if (base.metrics[i].name == "effort_energy") it_energy = static_cast<long>(i);
  }
  ASSERT_GE(it_end, 0);
  ASSERT_GE(it_energy, 0);
  EXPECT_NEAR(base.metrics[static_cast<size_t>(it_energy)].value, energy(v0)[1], 1e-3 * energy(v0)[1]);
  for (int k = 0; k < 3; ++k) {
    std::array<double, 3> up = v0, down = v0;
    up[static_cast<size_t>(k)] += 1e-6;
    down[static_cast<size_t>(k)] -= 1e-6;
    const Eigen::Vector2d fd = (energy(up) - energy(down)) / 2e-6;
    std::printf("  d/dv%d: t_end %.9f (closed form %.9f), effort_energy %.6f (closed form %.6f)\n", k + 1,
                G(it_end, k), fd[0], G(it_energy, k), fd[1]);
    EXPECT_NEAR(G(it_end, k), fd[0], 1e-8 * std::abs(fd[0]));
    // The plan's trapezoid (samples on the knots, |τ|² right-sided there) differs from the
    // integral by O(step) at each jump: within 1e-3 of the largest of the three derivatives (3.47).
    EXPECT_NEAR(G(it_energy, k), fd[1], 1e-3 * 3.47);
  }
  // The knots are on the grid (integrator breakpoints) and the grid moves with them: the columns
  // are the derivatives of the plan, which is RK4-accurate on every part. (With the knots inside
  // steps and jump terms: 3e-5 relative at 1e-4 s; without the jump terms 9e-3.)
  EXPECT_LT(worst, 2e-4 * scale);
}

// A parameter's column does not depend on which other parameters are requested with it. Under
// `t1: end` the whole grid moves with every parameter of the law, so every knot moves relative
// to it, also a knot whose own time does not depend on the requested parameter (the knot t1 =
// 2Δτ/v1 when only v3 is requested): each needs its jump term. Before this was followed, d/dv3
// requested alone differed from d/dv3 requested with v1 (the 2R circle's d peak_effort/dv16:
// −1.74 alone, +0.170 with v5; exact +0.169). Both forms of the law, state and metrics. (The
// segments form also needs the law's end to be the last part's left limit whatever the rounding
// of t1 against the knot's text: TimeLaw::symbolic_text.)
TEST(Sensitivity, UnderATimeLawEveryParameterSubsetGivesTheSameColumns) {
  for (const std::string law : {"knot_speeds: [v1, v2, v3]", "segments: [v1, v2, v3, v2]"}) {
    SCOPED_TRACE(law);
    const Planned base = plan_with(io::parse_scenario(rotor_on_a_law(law, 5e-4), "rotor.yaml"));
    SensitivityOptions all;
    all.parameters = {"v1", "v2", "v3"};
    const PlanSensitivity full = plan_sensitivity(*base.problem, base.plan, all);
    const Eigen::MatrixXd G = metric_gradients(*base.problem, base.plan, full, base.metrics);
    ASSERT_GT(G.cwiseAbs().maxCoeff(), 0.0);
    const std::vector<std::vector<std::string>> subsets = {{"v1"}, {"v2"}, {"v3"}, {"v3", "v1"}, {"v2", "v3"}};
    for (const auto& subset : subsets) {
      SensitivityOptions opt;
      opt.parameters = subset;
      const PlanSensitivity part = plan_sensitivity(*base.problem, base.plan, opt);
      const Eigen::MatrixXd Gp = metric_gradients(*base.problem, base.plan, part, base.metrics);
      ASSERT_EQ(part.dx.size(), full.dx.size());
      for (size_t c = 0; c < subset.size(); ++c) {
        const long k = subset[c][1] - '1';  // the column of v1, v2, v3 in the full request
        double worst = 0, scale = 0;
        for (size_t j = 0; j < full.dx.size(); ++j) {
          worst = std::max(worst, (part.dx[j].col(static_cast<long>(c)) - full.dx[j].col(k)).cwiseAbs().maxCoeff());
          scale = std::max(scale, full.dx[j].col(k).cwiseAbs().maxCoeff());
        }
        EXPECT_LE(worst, 1e-9 * scale) << subset[c] << " requested with " << subset.size() - 1 << " other(s)";
        for (long i = 0; i < G.rows(); ++i)
          EXPECT_NEAR(Gp(i, static_cast<long>(c)), G(i, k), 1e-9 * std::max(1.0, std::abs(G(i, k))))
              << base.metrics[static_cast<size_t>(i)].name << ", " << subset[c];
      }
    }
  }
}

// The 2R circle of examples/planar_2r_circle on a 16-part knot-speed law: ∂ peak_effort(q2)/∂v_i
// against the closed form along the path (tests/topp_reference.hpp: hand-written 2R dynamics on
// the closed-form inverse kinematics, the law's s, ṡ, s̈ in closed form; no refdyn code), with the
// parameter requested alone and with others. The peak is differentiated at the plan's argmax
// sample k* (the envelope rule): the closed form's effort at the k*-th time of the grid, which
// moves with the knots (grid_time). The knots being breakpoints, the sample lies at a fixed
// fraction of its part, so the peak depends on the two speeds of that part only: their columns are
// compared with the closed form, and the other speeds' columns, exactly 0 in closed form, are
// checked to be 0 to rounding.
TEST(Sensitivity, TheRetimedCircleMatchesTheClosedFormAloneAndInSubsets) {
  const int K = 16;
  const double Tp = 2.0, dtau = Tp / K;
  std::vector<double> v0(K + 1, 0.0);
  for (int i = 1; i < K; ++i) v0[static_cast<size_t>(i)] = 0.9 + 0.5 * std::sin(std::numbers::pi * i / K) + 0.05 * (i % 3);
  std::string params, names;
  for (int i = 1; i < K; ++i) {
    params += "  v" + std::to_string(i) + ": " + fmt(v0[static_cast<size_t>(i)]) + "\n";
    names += (i > 1 ? ", v" : "v") + std::to_string(i);
  }
  const std::string yaml =
      "name: circle\nparameters:\n  L1: 0.5\n  L2: 0.4\n  m1: 2.0\n  m2: 1.5\n  cx: 0.6\n  cy: 0.2\n  R: 0.15\n"
      "  Tp: 2\n" + params +
      "  ex0: cx + R\n  ey0: cy\n  q20: acos((ex0^2 + ey0^2 - L1^2 - L2^2)/(2*L1*L2))\n"
      "  q10: atan2(ey0, ex0) - atan2(L2*sin(q20), L1 + L2*cos(q20))\n"
      "model:\n  gravity: [0, -9.81, 0]\n  links:\n"
      "    - {name: upper, joint: q1, parent: base, type: revolute, axis: [0, 0, 1],\n"
      "       mass: m1, com: [L1/2, 0, 0], inertia: [0.001, m1*L1^2/12, m1*L1^2/12]}\n"
      "    - {name: fore, joint: q2, parent: upper, type: revolute, axis: [0, 0, 1], origin: {xyz: [L1, 0, 0]},\n"
      "       mass: m2, com: [L2/2, 0, 0], inertia: [0.001, m2*L2^2/12, m2*L2^2/12]}\n"
      "  points:\n    E: {link: fore, position: [L2, 0, 0]}\n"
      "constraints:\n"
      "  - {name: ex, kind: point_coordinate, point: E, axis: x, function: cx + R*cos(2*pi*t/Tp)}\n"
      "  - {name: ey, kind: point_coordinate, point: E, axis: y, function: cy + R*sin(2*pi*t/Tp)}\n"
      "time_law: {task_duration: Tp, knot_speeds: [" + names + "]}\n"
      "partition:\n  independent: []\n"
      "baumgarte: {alpha: 100, beta: 50}\n"
      "initial:\n  q: {q1: q10, q2: q20}\n  qd: {q1: 0, q2: 0}\n"
      "integrator: {method: rk4, step: 2e-4, t0: 0, t1: end}\n";
  const Planned base = plan_with(io::parse_scenario(yaml, "circle.yaml"));
  long metric = -1;
  for (size_t i = 0; i < base.metrics.size(); ++i)
    if (base.metrics[i].name == "peak_effort(q2)") metric = static_cast<long>(i);
  ASSERT_GE(metric, 0);
  const Metric& peak = base.metrics[static_cast<size_t>(metric)];
  const std::vector<long> counts = part_steps(base.problem->time_law_knots, 2e-4);
  // The closed form: q2's effort at the k-th grid time (grid_time) of the law with speeds v.
  const test::TwoLinkArm arm;
  const test::Circle circle;
  auto effort = [&](const std::vector<double>& v, long k) {
    std::vector<double> knots(K + 1, 0.0);
    for (int i = 0; i < K; ++i)
      knots[static_cast<size_t>(i) + 1] = knots[static_cast<size_t>(i)] + 2 * dtau / (v[static_cast<size_t>(i)] + v[static_cast<size_t>(i) + 1]);
    const double t = grid_time(knots, counts, static_cast<size_t>(k));
    int i = 0;
    while (i < K - 1 && t >= knots[static_cast<size_t>(i) + 1]) ++i;
    const double vi = v[static_cast<size_t>(i)], vn = v[static_cast<size_t>(i) + 1];
    const double h = t - knots[static_cast<size_t>(i)], a = (vn * vn - vi * vi) / (2 * dtau);
    const double s = i * dtau + vi * h + 0.5 * a * h * h, sd = vi + a * h;
    const double w = 2 * std::numbers::pi / Tp;  // θ = w s
    Eigen::Vector2d q, dq, ddq;
    test::circle_ik(arm, circle, w * s, q, dq, ddq);
    const Eigen::Vector2d qd = dq * (w * sd), qdd = dq * (w * a) + ddq * (w * sd) * (w * sd);
    return arm.inverse_dynamics(q, qd, qdd)[1];
  };
  EXPECT_NEAR(peak.value, std::abs(effort(v0, peak.sample)), 2e-3 * peak.value) << "the plan's peak vs the closed form";
  // The part holding k* (t in [t_p, t_{p+1}), as the closed form and the law take it): its speeds
  // v_p and v_{p+1} (v_0 = v_K = 0 are no parameters).
  const std::vector<double>& knots = base.problem->time_law_knots;
  const int part = static_cast<int>(std::upper_bound(knots.begin(), knots.end(), base.plan.t[static_cast<size_t>(peak.sample)]) -
                                    knots.begin()) - 1;
  std::vector<std::string> own;
  for (int i : {part, part + 1})
    if (i >= 1 && i < K) own.push_back(std::string("v").append(std::to_string(i)));
  ASSERT_FALSE(own.empty()) << "the peak lies in part " << part;
  std::vector<std::vector<std::string>> requests = {{"v8"}, {"v3", "v8"}, {"v15"}};
  for (const std::string& v : own) {
    requests.push_back({v});
    requests.push_back({"v3", v, "v8"});
  }
  // The closed form's differences (τ(v + δ) − τ(v − δ))/2δ, δ = 1e-6, of a derivative that is
  // exactly 0 are whole ulps of τ over 2δ, not 0 (here 0 or 2 ulps of |τ| = 2.37: 4.4e-10); the
  // hand-written τ = M q̈ + c + g (and the sample's time, a sum of the parts' durations) rounds
  // within a few ulps of |τ| at each of the two evaluations: allowed 4 eps |τ| each, so
  // 4 eps |τ|/δ in all (2.1e-9 here). refdyn's columns of those speeds are ~1e-15 (the moving
  // grid's terms cancelling to rounding).
  const double delta = 1e-6, rounding = 4 * std::numeric_limits<double>::epsilon() * peak.value / delta;
  double worst = 0, largest = 0;
  for (const auto& request : requests) {
    SensitivityOptions opt;
    opt.parameters = request;
    const PlanSensitivity s = plan_sensitivity(*base.problem, base.plan, opt);
    const Eigen::MatrixXd G = metric_gradients(*base.problem, base.plan, s, base.metrics);
    for (size_t c = 0; c < request.size(); ++c) {
      const size_t i = static_cast<size_t>(std::stoi(request[c].substr(1)));
      std::vector<double> up = v0, down = v0;
      up[i] += delta;
      down[i] -= delta;
      const double closed = peak.sign * (effort(up, peak.sample) - effort(down, peak.sample)) / (2 * delta);
      const double got = G(metric, static_cast<long>(c));
      const bool of_part = std::find(own.begin(), own.end(), request[c]) != own.end();
      std::printf("  d peak_effort(q2)/d%s with %zu requested: %.10f (closed form %.10f)%s\n", request[c].c_str(),
                  request.size(), got, closed, of_part ? ", a speed of the peak's part" : "");
      if (of_part) {
        worst = std::max(worst, std::abs(got - closed) / std::abs(closed));
        largest = std::max(largest, std::abs(closed));
      }
      // The plan at 2e-4 s, its knots on the grid: measured 7e-8 relative (v13), 8e-10 (v14).
      EXPECT_NEAR(got, closed, 1e-5 * std::abs(closed) + rounding) << request[c] << " of " << request.size();
    }
  }
  EXPECT_GT(largest, 1e3 * rounding);  // the comparison is not one of zeros only
  std::printf("retimed circle: worst relative difference to the closed form %.2e (the peak's part's speeds); |peak| %.4f, "
              "the closed form's rounding %.2e\n", worst, peak.value, rounding);
}

/// The 2R circle of examples/planar_2r_circle on a K-part knot-speed law with K − 1 scalar
/// parameters v1 … v_{K−1} (uneven speeds), effort metrics, `t1: end`, RK4 at `step`.
std::string circle_on_k_parts(int K, double step) {
  std::string params, names;
  for (int i = 1; i < K; ++i) {
    params += "  v" + std::to_string(i) + ": " +
              fmt(std::round(1e4 * (0.9 + 0.5 * std::sin(std::numbers::pi * i / K) + 0.05 * (i % 3))) / 1e4) + "\n";
    names += (i > 1 ? ", v" : "v") + std::to_string(i);
  }
  return "name: circle\nparameters:\n  L1: 0.5\n  L2: 0.4\n  m1: 2.0\n  m2: 1.5\n  cx: 0.6\n  cy: 0.2\n  R: 0.15\n"
         "  Tp: 2\n" + params +
         "  ex0: cx + R\n  ey0: cy\n  q20: acos((ex0^2 + ey0^2 - L1^2 - L2^2)/(2*L1*L2))\n"
         "  q10: atan2(ey0, ex0) - atan2(L2*sin(q20), L1 + L2*cos(q20))\n"
         "model:\n  gravity: [0, -9.81, 0]\n  links:\n"
         "    - {name: upper, joint: q1, parent: base, type: revolute, axis: [0, 0, 1],\n"
         "       mass: m1, com: [L1/2, 0, 0], inertia: [0.001, m1*L1^2/12, m1*L1^2/12]}\n"
         "    - {name: fore, joint: q2, parent: upper, type: revolute, axis: [0, 0, 1], origin: {xyz: [L1, 0, 0]},\n"
         "       mass: m2, com: [L2/2, 0, 0], inertia: [0.001, m2*L2^2/12, m2*L2^2/12]}\n"
         "  points:\n    E: {link: fore, position: [L2, 0, 0]}\n"
         "constraints:\n"
         "  - {name: ex, kind: point_coordinate, point: E, axis: x, function: cx + R*cos(2*pi*t/Tp)}\n"
         "  - {name: ey, kind: point_coordinate, point: E, axis: y, function: cy + R*sin(2*pi*t/Tp)}\n"
         "time_law: {task_duration: Tp, knot_speeds: [" + names + "]}\n"
         "partition:\n  independent: []\n"
         "baumgarte: {alpha: 100, beta: 50}\n"
         "initial:\n  q: {q1: q10, q2: q20}\n  qd: {q1: 0, q2: 0}\n"
         "integrator: {method: rk4, step: " + fmt(step) + ", t0: 0, t1: end}\n";
}

// Issue 34, item 2: the time law is evaluated natively under the sensitivities (no generated text
// of every knot: K = 128 was refused at 65 536 characters), so a 128-part law is differentiated
// like a 4-part one. Every metric and the state at four samples, for knot speeds at the start, in
// the middle and at the end and for the task duration (which the law and the path both use),
// against fourth-order central differences of whole plans (in the test, not the engine), 1e-5
// relative: the columns are the derivatives of the computed plan (docs/sensitivity.md).
TEST(Sensitivity, AtManyPartsTheLawsColumnsMatchCentralDifferences) {
  check_against_differences(circle_on_k_parts(128, 1e-3), {"v1", "v64", "v127", "Tp"}, 1e-5);
}

// K = 512 (511 parameters): a knot speed's column of the state against central differences.
TEST(Sensitivity, FiveHundredTwelvePartsPlanWithSensitivities) {
  const std::string yaml = circle_on_k_parts(512, 1e-3);
  check_against_differences(yaml, {"v300"}, 1e-5, 1e-3, kStates);
}

TEST(Sensitivity, BadRequestsAreRefusedWithAHint) {
  const ScenarioSpec spec = io::parse_scenario(paper_with_duration(), "p.yaml");
  const Planned base = plan_with(spec);
  SensitivityOptions opt;
  opt.parameters = {"Tx"};
  test::expect_error_mentioning([&] { plan_sensitivity(*base.problem, base.plan, opt); }, {"did you mean 'Tz'"});
  opt.parameters = {};
  test::expect_error_mentioning([&] { plan_sensitivity(*base.problem, base.plan, opt); }, {"at least one"});
  opt.parameters = {"Tz", "Tz"};
  test::expect_error_mentioning([&] { plan_sensitivity(*base.problem, base.plan, opt); }, {"twice"});
}

}  // namespace
}  // namespace refdyn
