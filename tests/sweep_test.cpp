// Experiments that expand into several runs: sweep, grid (cartesian product, first key slowest)
// and monte_carlo (samples drawn in build_problem from std::mt19937_64 with our own uniform and
// Box–Muller normal, docs/scenario.md "experiments"). Checked: order, count, names and values
// (in the controller's gains and the initial state), bit-for-bit reproducibility from the seed
// against an independent computation here, statistics of 20,000 samples, max_runs, and every
// error of the syntax.
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace refdyn;

namespace {

// The minimal test scenario (a horizontal planar 2R arm: g(q) = 0 about the vertical joint
// axes) with a PD controller, `extra` and `experiments` appended.
std::string arm(const std::string& experiments, const std::string& extra = "") {
  static const std::string minimal = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/tests/data/good/minimal.yaml");
  return minimal + "\ncontroller: {type: pd_gravity, kp: [1, 1], kd: [1, 1]}\n" + extra + "experiments:\n" + experiments;
}

std::unique_ptr<Problem> build(const std::string& text) { return io::parse_problem(text, "sweep.yaml"); }

// K_p of a PD + gravity controller, read from its torque: τ = g(q) − K_p e − K_d ė with g = 0
// (horizontal arm), q̇ = q̂ = q̂̇ = 0 and e = unit vector j.
Eigen::VectorXd kp_of(const Problem& p, const Experiment& ex) {
  auto ctrl = ex.make_controller(p.model);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(2);
  Eigen::VectorXd kp(2), tau(2);
  for (int j = 0; j < 2; ++j) {
    Eigen::VectorXd q = zero;
    q[j] = 1.0;
    ctrl->compute(0.0, q, zero, ReferenceSample{zero, zero, zero}, tau);
    kp[j] = -tau[j];
  }
  return kp;
}

// The definition in docs/scenario.md, computed here from std::mt19937_64 directly. Every
// operation rounded on its own: the volatile product keeps the compiler from fusing a + b·c.
double u01(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }
double normal(std::mt19937_64& g, double mean, double std) {
  const double u1 = u01(g), u2 = u01(g);
  volatile double spread = std * (std::sqrt(-2.0 * std::log(1.0 - u1)) * std::cos(2.0 * std::numbers::pi * u2));
  return mean + spread;
}
double uniform(std::mt19937_64& g, double low, double high) {
  volatile double spread = (high - low) * u01(g);
  return low + spread;
}

double value(const Experiment& e, const std::string& name) {
  for (const auto& [k, v] : e.sweep)
    if (k == name) return v;
  ADD_FAILURE() << e.name << " has no value for '" << name << "'";
  return std::nan("");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// grid

TEST(Grid, CartesianProductFirstKeySlowestValuesReachGainsAndInitialState) {
  const auto p = build(arm(R"(  - name: "kp{kp}_m{m}"
    grid:
      kp: [100, 2*100]
      m: [1, 2, 3]
    initial: {q: {j1: m*deg}, qd: {j2: kp/100}}
    controller: {type: pd_gravity, kp: [kp, 2*kp], kd: [m, m]}
  - name: after
)"));
  ASSERT_EQ(p->experiments.size(), 7u);
  int i = 0;
  for (double kp : {100.0, 200.0})
    for (double m : {1.0, 2.0, 3.0}) {
      const Experiment& e = *p->experiments[i++];
      char name[64];
      std::snprintf(name, sizeof name, "kp%g_m%g", kp, m);
      EXPECT_EQ(e.name, name);
      ASSERT_EQ(e.sweep.size(), 2u);
      EXPECT_EQ(e.sweep[0].first, "kp");
      EXPECT_EQ(e.sweep[1].first, "m");
      EXPECT_EQ(e.sweep[0].second, kp);
      EXPECT_EQ(e.sweep[1].second, m);
      EXPECT_EQ(e.sample, -1);
      EXPECT_DOUBLE_EQ(e.q0[0], m * std::numbers::pi / 180);
      EXPECT_EQ(e.q0[1], p->q0[1]);  // not given: where the plan starts
      EXPECT_EQ(e.qd0[0], 0.0);
      EXPECT_EQ(e.qd0[1], kp / 100);
      const Eigen::VectorXd gains = kp_of(*p, e);
      EXPECT_DOUBLE_EQ(gains[0], kp) << e.name;
      EXPECT_DOUBLE_EQ(gains[1], 2 * kp) << e.name;
    }
  EXPECT_EQ(p->experiments[6]->name, "after");
  EXPECT_TRUE(p->experiments[6]->sweep.empty());
  EXPECT_DOUBLE_EQ(kp_of(*p, *p->experiments[6])[0], 1.0);  // the top-level controller
}

TEST(Grid, DefaultNamesAreUniqueAndAOneRunExperimentKeepsItsName) {
  const auto p = build(arm(R"(  - grid: {a: [1, 2], b: [3, 4, 5, 6, 7, 8]}
  - sweep: {c: [1]}
  - {}
  - grid: {d: [1]}
)"));
  std::vector<std::string> names;
  for (const auto& e : p->experiments) names.push_back(e->name);
  EXPECT_EQ(names, (std::vector<std::string>{"run0_00", "run0_01", "run0_02", "run0_03", "run0_04", "run0_05",
                                             "run0_06", "run0_07", "run0_08", "run0_09", "run0_10", "run0_11",
                                             "run1", "run2", "run3"}));
  EXPECT_EQ(value(*p->experiments[11], "a"), 2.0);
  EXPECT_EQ(value(*p->experiments[11], "b"), 8.0);
}

TEST(Grid, ASweepWithoutNameNowGetsNumberedNames) {
  const auto p = build(arm("  - sweep: {d: [5, 20]}\n"));
  ASSERT_EQ(p->experiments.size(), 2u);
  EXPECT_EQ(p->experiments[0]->name, "run0_0");
  EXPECT_EQ(p->experiments[1]->name, "run0_1");
}

TEST(Grid, CountsAgainstMaxRunsBeforeExpandingEvenBeyondAnyInteger) {
  test::expect_error_mentioning(
      [] { build(arm("  - grid: {a: [1, 2, 3], b: [1, 2, 3]}\n  - name: one\n", "limits: {max_runs: 9}\n")); },
      {"sweep.yaml:", "experiments: 10 runs", "limits.max_runs = 9", "experiments[0] gives 9", "hint"});
  EXPECT_EQ(build(arm("  - grid: {a: [1, 2, 3], b: [1, 2, 3]}\n", "limits: {max_runs: 9}\n"))->experiments.size(), 9u);
  // 100^10 = 1e20 runs: more than any 64-bit count; rejected before anything is expanded.
  std::string values = "[";
  for (int k = 0; k < 100; ++k) values += (k ? ", " : "") + std::to_string(k);
  values += "]";
  std::string grid = "  - grid: {";
  for (int k = 0; k < 10; ++k) grid += (k ? ", " : "") + std::string("p") + std::to_string(k) + ": " + values;
  grid += "}\n";
  test::expect_error_mentioning([&] { build(arm(grid)); }, {"experiments: 1e+20 runs", "limits.max_runs = 10000"});
}

// ---------------------------------------------------------------------------------------------
// monte_carlo

namespace {
const char* kMc = R"(  - name: "mc{sample}"
    monte_carlo:
      samples: SAMPLES
      seed: SEED
      distributions:
        dq1: {normal: {mean: 0.5, std: 2}}
        s: {uniform: {low: 0.5, high: 3}}
    initial: {q: {j1: dq1}}
    controller: {type: pd_gravity, kp: [s, 1], kd: [1, 1]}
)";

std::string mc(long samples, const std::string& seed, const char* text = kMc) {
  std::string t = text;
  t.replace(t.find("SAMPLES"), 7, std::to_string(samples));
  t.replace(t.find("SEED"), 4, seed);
  return t;
}
}  // namespace

TEST(MonteCarlo, ValuesAreTheDocumentedDrawsFromMt19937_64BitForBit) {
  const auto p = build(arm(mc(12, "42")));
  ASSERT_EQ(p->experiments.size(), 12u);
  std::mt19937_64 g(42);
  for (int i = 0; i < 12; ++i) {
    const Experiment& e = *p->experiments[i];
    // Draw order: per sample, the distributions in the order written; a normal takes two
    // uniforms (u1, u2), a uniform one.
    const double dq1 = normal(g, 0.5, 2.0);
    const double s = uniform(g, 0.5, 3.0);
    EXPECT_EQ(e.name, "mc" + std::string(i < 10 ? "0" : "") + std::to_string(i));
    EXPECT_EQ(e.sample, i);
    EXPECT_EQ(e.seed, 42u);
    ASSERT_EQ(e.sweep.size(), 2u);
    EXPECT_EQ(e.sweep[0].first, "dq1");
    EXPECT_EQ(e.sweep[1].first, "s");
    EXPECT_EQ(e.sweep[0].second, dq1) << "sample " << i;
    EXPECT_EQ(e.sweep[1].second, s) << "sample " << i;
    EXPECT_EQ(e.q0[0], dq1);                  // reaches the initial state …
    EXPECT_DOUBLE_EQ(kp_of(*p, e)[0], s);     // … and the controller
  }
  // Pinned: the first raw output of std::mt19937_64 seeded with 42 and the first uniform, as
  // literals, so that a non-conforming generator or a changed formula shows up here.
  std::mt19937_64 raw(42);
  const std::uint64_t first = raw();
  EXPECT_EQ(first, 13930160852258120406ull);
  EXPECT_EQ(static_cast<double>(first >> 11) * 0x1.0p-53, 0x1.82a3befaddcbcp-1);  // 0.75515553295453897
  // The standard's own check value: the 10000th output of the default-seeded engine.
  std::mt19937_64 d;
  d.discard(9999);
  EXPECT_EQ(d(), 9981545732273789042ull);
}

TEST(MonteCarlo, SameSeedSameValuesOtherSeedOtherValuesIndependentOfTheRest) {
  const auto a = build(arm(mc(50, "7")));
  const auto b = build(arm(mc(50, "7")));
  const auto c = build(arm(mc(50, "8")));
  // The same experiment after another one, with more samples, other parameters and another
  // scenario around it: its first 50 samples are the same.
  std::string other = arm("  - name: first\n    sweep: {x: [1]}\n" + mc(80, "7"));
  other.replace(other.find("  L2: 0.4\n"), 10, "  L2: 0.45\n  k: 3\n");
  const auto d = build(other);
  ASSERT_EQ(d->experiments.size(), 81u);
  int differ = 0;
  for (int i = 0; i < 50; ++i) {
    for (int v = 0; v < 2; ++v) {
      EXPECT_EQ(a->experiments[i]->sweep[v].second, b->experiments[i]->sweep[v].second);
      EXPECT_EQ(a->experiments[i]->sweep[v].second, d->experiments[i + 1]->sweep[v].second);
      differ += a->experiments[i]->sweep[v].second != c->experiments[i]->sweep[v].second;
    }
  }
  EXPECT_EQ(differ, 100) << "seed 8 should give other values than seed 7";
  // Seeds use the whole unsigned 64-bit range.
  const auto big = build(arm(mc(3, "18446744073709551615")));
  std::mt19937_64 g(18446744073709551615ull);
  EXPECT_EQ(big->experiments[0]->seed, 18446744073709551615ull);
  EXPECT_EQ(big->experiments[0]->sweep[0].second, normal(g, 0.5, 2.0));
}

TEST(MonteCarlo, TwentyThousandSamplesHaveTheirDistributionsMoments) {
  const char* text = R"(  - monte_carlo:
      samples: 20000
      seed: 2026
      distributions:
        n: {normal: {mean: -3, std: 0.25}}
        u: {uniform: {low: 2, high: 5}}
        z: {normal: {mean: 1, std: 0}}
)";
  const auto p = build(arm(text, "limits: {max_runs: 20000}\n"));
  ASSERT_EQ(p->experiments.size(), 20000u);
  EXPECT_EQ(p->experiments[0]->name, "run0_00000");
  EXPECT_EQ(p->experiments[19999]->name, "run0_19999");
  const double N = 20000;
  double sn = 0, snn = 0, su = 0, umin = 1e9, umax = -1e9;
  int below_mean = 0;
  for (const auto& e : p->experiments) {
    const double n = e->sweep[0].second, u = e->sweep[1].second;
    sn += n;
    snn += n * n;
    su += u;
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    below_mean += n < -3;
    EXPECT_EQ(e->sweep[2].second, 1.0);  // std 0: the mean exactly
  }
  const double mean = sn / N, sd = std::sqrt((snn - N * mean * mean) / (N - 1));
  EXPECT_NEAR(mean, -3, 4 * 0.25 / std::sqrt(N));
  EXPECT_NEAR(sd, 0.25, 4 * 0.25 / std::sqrt(2 * N));
  EXPECT_NEAR(below_mean / N, 0.5, 4 * 0.5 / std::sqrt(N));
  EXPECT_GE(umin, 2.0);
  EXPECT_LE(umax, 5.0);
  EXPECT_LT(umin, 2.0 + 0.01);
  EXPECT_GT(umax, 5.0 - 0.01);
  EXPECT_NEAR(su / N, 3.5, 4 * (3 / std::sqrt(12.0)) / std::sqrt(N));
}

TEST(MonteCarlo, SummaryJsonRecordsValuesSampleAndSeed) {
  const auto p = build(arm(mc(2, "5")));
  const io::Results r = io::run_problem(*p, [] { io::RunOptions o; o.track = true; return o; }());
  const std::string json = json_text(io::summary_json(*p, r));
  EXPECT_NE(json.find("\"sweep\": {\"dq1\": "), std::string::npos) << json;
  EXPECT_NE(json.find("\"sample\": 1"), std::string::npos) << json;
  EXPECT_NE(json.find("\"seed\": 5"), std::string::npos) << json;
  // The largest seed is written exactly (not as a negative or rounded number).
  const auto big = build(arm(mc(1, "18446744073709551615")));
  const std::string big_json = json_text(io::summary_json(*big, io::run_problem(*big, [] { io::RunOptions o; o.track = true; return o; }())));
  EXPECT_NE(big_json.find("\"seed\": 18446744073709551615"), std::string::npos) << big_json;
}

// ---------------------------------------------------------------------------------------------
// Errors: one line FILE:LINE: KEY: message.

TEST(SweepErrors, EachMistakeNamesItsKey) {
  struct Case {
    std::string experiments, extra;
    std::vector<std::string> needles;
  };
  const std::vector<Case> cases{
      {"  - {sweep: {a: [1]}, grid: {b: [1]}}\n", "",
       {"sweep.yaml:", "experiments[0].grid", "at most one of sweep, grid and monte_carlo", "'sweep' and 'grid'"}},
      {"  - grid: {b: [1]}\n    monte_carlo: {samples: 1, seed: 1, distributions: {x: {normal: {mean: 0, std: 1}}}}\n", "",
       {"sweep.yaml:", "experiments[0].monte_carlo", "'grid' and 'monte_carlo'"}},
      {"  - grid: {a: [1], b: []}\n", "", {"sweep.yaml:", "experiments[0].grid.b", "non-empty list"}},
      {"  - grid: {}\n", "", {"sweep.yaml:", "experiments[0].grid", "at least one parameter"}},
      {"  - grid:\n", "", {"sweep.yaml:", "experiments[0].grid", "at least one parameter", "got nothing"}},
      {"  - monte_carlo:\n", "", {"sweep.yaml:", "experiments[0].monte_carlo", "samples, seed and distributions"}},
      {"  - grid: {a: 3}\n", "", {"experiments[0].grid.a", "non-empty list", "got '3'"}},
      {"  - grid: {L1: [1, 2]}\n", "", {"sweep.yaml:", "experiments[0].grid.L1", "name of a parameter"}},
      {"  - grid: {pi: [1, 2]}\n", "", {"experiments[0].grid.pi", "name of a parameter (or a constant)"}},
      {"  - sweep: {deg: [1, 2]}\n", "", {"experiments[0].sweep.deg", "name of a parameter (or a constant)"}},
      {"  - grid: {a: [1, x]}\n", "", {"experiments[0].grid.a", "unknown"}},
      {"  - name: g\n    grid: {a: [1, 2]}\n", "", {"experiments[0].name", "duplicate experiment name 'g'", "{a}"}},
      {"  - name: \"m{sample}\"\n    grid: {a: [1, 2]}\n", "", {"experiments[0].name", "placeholder '{sample}'", "not a parameter of this experiment", "it has {a}"}},
      {mc(0, "1"), "", {"sweep.yaml:", "experiments[0].monte_carlo.samples", "whole number >= 1", "got 0"}},
      {mc(1, "1").replace(mc(1, "1").find("samples: 1"), 10, "samples: 2.5"), "",
       {"experiments[0].monte_carlo.samples", "whole number >= 1", "got 2.5"}},
      {mc(1, "-1"), "", {"sweep.yaml:", "experiments[0].monte_carlo.seed", "whole number 0", "got '-1'"}},
      {mc(1, "1.5"), "", {"experiments[0].monte_carlo.seed", "got '1.5'"}},
      {mc(1, "18446744073709551616"), "", {"experiments[0].monte_carlo.seed", "18446744073709551615"}},
      {mc(3, "1"), "limits: {max_runs: 2}\n",
       {"sweep.yaml:", "experiments: 3 runs", "limits.max_runs = 2", "hint"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {gaussian: {mean: 0, std: 1}}}}\n", "",
       {"sweep.yaml:", "experiments[0].monte_carlo.distributions.x.gaussian", "unknown distribution 'gaussian'",
        "normal", "uniform"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {normal: {mean: 0, std: -0.1}}}}\n", "",
       {"sweep.yaml:", "experiments[0].monte_carlo.distributions.x.normal.std", ">= 0", "got -0.1"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {uniform: {low: 2, high: 1}}}}\n", "",
       {"sweep.yaml:", "experiments[0].monte_carlo.distributions.x.uniform", "low <= high", "low = 2", "high = 1"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {normal: {mean: 0}}}}\n", "",
       {"experiments[0].monte_carlo.distributions.x.normal.std", "missing"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {normal: {mean: 0, sd: 1}}}}\n", "",
       {"experiments[0].monte_carlo.distributions.x.normal.sd", "unknown key 'sd'"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {x: {normal: {mean: 0, std: 1}, uniform: {low: 0, high: 1}}}}\n",
       "", {"experiments[0].monte_carlo.distributions.x", "exactly one distribution"}},
      {"  - monte_carlo: {samples: 1, distributions: {x: {normal: {mean: 0, std: 1}}}}\n", "",
       {"experiments[0].monte_carlo.seed", "missing"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {}}\n", "",
       {"experiments[0].monte_carlo.distributions", "at least one parameter"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {L2: {normal: {mean: 0, std: 1}}}}\n", "",
       {"experiments[0].monte_carlo.distributions.L2", "name of a parameter"}},
      {"  - monte_carlo: {samples: 1, seed: 1, distributions: {sample: {normal: {mean: 0, std: 1}}}}\n", "",
       {"experiments[0].monte_carlo.distributions.sample", "reserved"}},
      {"  - monte_carlo: {samples: 1, seed: 1, sed: 2, distributions: {x: {normal: {mean: 0, std: 1}}}}\n", "",
       {"experiments[0].monte_carlo.sed", "did you mean 'seed'"}},
      {"  - name: mc\n    monte_carlo: {samples: 2, seed: 1, distributions: {x: {normal: {mean: 0, std: 1}}}}\n", "",
       {"experiments[0].name", "duplicate experiment name 'mc'", "{sample}"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.experiments);
    test::expect_error_mentioning([&] { build(arm(c.experiments, c.extra)); }, c.needles);
  }
}

// ---------------------------------------------------------------------------------------------
// The example: grid and Monte Carlo runs track the circle.
TEST(Example, PlanarCircleSweepsTrackEveryRun) {
  const auto p = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/sweeps.yaml");
  std::vector<std::string> names;
  for (const auto& e : p->experiments) names.push_back(e->name);
  EXPECT_EQ(names, (std::vector<std::string>{"d5_e2", "d5_e5", "d20_e2", "d20_e5", "mc0", "mc1", "mc2", "mc3"}));
  io::RunOptions o;
  o.track = true;
  const io::Results r = io::run_problem(*p, o);
  ASSERT_TRUE(r.plan.summary.ok()) << r.plan.summary.message;
  ASSERT_EQ(r.runs.size(), 8u);
  // No plant forces: the plant is the controller's model, so each joint error follows the
  // computed-torque closed form e(t) = (e0 + (ė0 + δ e0) t) e^(−δt), with this run's δ.
  for (const auto& run : r.runs) {
    const ClosedLoopResult& c = run.result;
    ASSERT_TRUE(c.summary.ok()) << run.experiment->name << ": " << c.summary.message;
    const double delta = run.experiment->sample >= 0 ? 10 * value(*run.experiment, "scale") : value(*run.experiment, "d");
    const int n = c.nq();
    ASSERT_EQ(c.t.size(), r.plan.t.size());
    double worst = 0, biggest = 0;
    for (int j = 0; j < n; ++j) {
      const double e0 = c.x[0][j] - c.q_ref[0][j], ed0 = c.x[0][n + j] - r.plan.x[0][n + j];
      for (size_t k = 0; k < c.t.size(); ++k) {
        const double e = c.x[k][j] - c.q_ref[k][j], t = c.t[k];
        worst = std::max(worst, std::abs(e - (e0 + (ed0 + delta * e0) * t) * std::exp(-delta * t)));
        biggest = std::max(biggest, std::abs(e));
      }
    }
    EXPECT_GT(biggest, 1e-3) << run.experiment->name << ": the start is disturbed";
    EXPECT_LT(worst, 1e-6) << run.experiment->name << ": the error differs from the closed form with this run's gain";
  }
}
