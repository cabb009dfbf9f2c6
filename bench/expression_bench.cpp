// Expression tape vs hand-written C++: value + gradient + Hessian of the two spec constraints
//   Φ1 = (x/a)² + (y/b)² − 1,                a = 0.5·cos45°, b = 0.25,      variables (x, y)
//   Φ2 = z − (z0 + dz(1 − cos(2πt/Tz))/2),   z0 = 0.6 + 0.5·sin45°, dz = 0.1, Tz = 5, vars (z, t)
// Both sides produce the same outputs (value, 2-gradient, 2×2 Hessian) through the same
// signature; the hand-written functions are noinline with the parameters as compile-time
// constants (the best a hand-written constraint can do). Inputs cycle through 64 random points.
// After the runs the medians and the ratio tape / hand-written are printed.
//
// Construction cost vs text length (BM_Construct_*): parse + GiNaC lowering + derivatives +
// tape compilation of generated texts of 1 KiB .. 64 KiB (the default ExpressionOptions::
// max_length), with a fitted complexity (expected: about linear, O(N)).
//   ./build/bench/expression_bench --benchmark_filter=Construct
//
//   ./build/bench/expression_bench            (add --benchmark_filter=Phi1 etc. as usual)
#include "refdyn/expression/expression.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kA = 0.35355339059327373;  // 0.5·cos45°
constexpr double kB = 0.25;
const double kZ0 = 0.6 + 0.5 * std::sin(kPi / 4);
constexpr double kDz = 0.1;
constexpr double kTz = 5.0;

constexpr int kPoints = 64;

std::array<std::array<double, 2>, kPoints> random_points(double lo0, double hi0, double lo1,
                                                         double hi1) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u0(lo0, hi0), u1(lo1, hi1);
  std::array<std::array<double, 2>, kPoints> p{};
  for (auto& x : p) x = {u0(rng), u1(rng)};
  return p;
}

const auto kPhi1Points = random_points(-0.4, 0.4, -0.3, 0.3);
const auto kPhi2Points = random_points(0.5, 1.2, 0.0, 10.0);

// Hand-written Φ1: value, gradient, Hessian.
__attribute__((noinline)) void phi1_hand(const double* x, double& v, double* g, double* H) {
  constexpr double ia2 = 1.0 / (kA * kA), ib2 = 1.0 / (kB * kB);
  const double px = x[0], py = x[1];
  v = px * px * ia2 + py * py * ib2 - 1.0;
  g[0] = 2.0 * ia2 * px;
  g[1] = 2.0 * ib2 * py;
  H[0] = 2.0 * ia2;
  H[1] = 0.0;
  H[2] = 0.0;
  H[3] = 2.0 * ib2;
}

// Hand-written Φ2 over (z, t).
__attribute__((noinline)) void phi2_hand(const double* x, double& v, double* g, double* H) {
  constexpr double w = 2.0 * kPi / kTz;
  const double z = x[0], t = x[1];
  const double s = std::sin(w * t), c = std::cos(w * t);
  v = z - (kZ0 + kDz * (1.0 - c) / 2.0);
  g[0] = 1.0;
  g[1] = -0.5 * kDz * w * s;
  H[0] = 0.0;
  H[1] = 0.0;
  H[2] = 0.0;
  H[3] = -0.5 * kDz * w * w * c;
}

const refdyn::Expression& phi1() {
  static const refdyn::Expression e("(x(E)/a)^2 + (y(E)/b)^2 - 1", {"x(E)", "y(E)"},
                                    {{"a", kA}, {"b", kB}});
  return e;
}

// Φ1 through the generic tape interpreter (quadratic kernel disabled), for reference.
const refdyn::Expression& phi1_generic() {
  static const refdyn::Expression e("(x(E)/a)^2 + (y(E)/b)^2 - 1", {"x(E)", "y(E)"},
                                    {{"a", kA}, {"b", kB}},
                                    refdyn::ExpressionOptions{.derivative_order = 2, .specialize = false});
  return e;
}

const refdyn::Expression& phi2() {
  static const refdyn::Expression e("z(E) - (z0 + dz*(1 - cos(2*pi*t/Tz))/2)", {"z(E)", "t"},
                                    {{"z0", kZ0}, {"dz", kDz}, {"Tz", kTz}});
  return e;
}

template <typename F>
void run(benchmark::State& state, const std::array<std::array<double, 2>, kPoints>& pts, F&& f) {
  double v = 0, g[2], H[4];
  unsigned i = 0;
  for (auto _ : state) {
    f(pts[i++ & (kPoints - 1)].data(), v, g, H);
    benchmark::DoNotOptimize(v);
    benchmark::DoNotOptimize(g);
    benchmark::DoNotOptimize(H);
    benchmark::ClobberMemory();
  }
}

void BM_Phi1_Hand(benchmark::State& state) { run(state, kPhi1Points, phi1_hand); }
void BM_Phi1_Tape(benchmark::State& state) {
  const auto& e = phi1();
  run(state, kPhi1Points,
      [&](const double* x, double& v, double* g, double* H) { e.evaluate(x, v, g, H); });
}
void BM_Phi1_TapeGeneric(benchmark::State& state) {
  const auto& e = phi1_generic();
  run(state, kPhi1Points,
      [&](const double* x, double& v, double* g, double* H) { e.evaluate(x, v, g, H); });
}
void BM_Phi2_Hand(benchmark::State& state) { run(state, kPhi2Points, phi2_hand); }
void BM_Phi2_Tape(benchmark::State& state) {
  const auto& e = phi2();
  run(state, kPhi2Points,
      [&](const double* x, double& v, double* g, double* H) { e.evaluate(x, v, g, H); });
}

// ---- construction cost vs length ----
/// "1+1+...+1" of about `bytes` characters.
std::string ones_text(std::size_t bytes) {
  std::string s = "1";
  while (s.size() + 2 <= bytes) s += "+1";
  return s;
}
/// "0 + sin(1*x)/1 + sin(2*x)/2 + ..." (distinct terms, each with its own derivatives).
std::string sines_text(std::size_t bytes) {
  std::string s = "0";
  for (int k = 1;; ++k) {
    std::string term = " + sin(" + std::to_string(k) + "*x)/" + std::to_string(k);
    if (s.size() + term.size() > bytes) break;
    s += term;
  }
  return s;
}
void construct(benchmark::State& state, const std::string& text) {
  for (auto _ : state) {
    refdyn::Expression e(text, {"x"});
    benchmark::DoNotOptimize(e.tape_size());
  }
  state.SetComplexityN(static_cast<benchmark::IterationCount>(text.size()));
  state.counters["bytes"] = static_cast<double>(text.size());
}
void BM_Construct_Ones(benchmark::State& state) { construct(state, ones_text(state.range(0))); }
void BM_Construct_Sines(benchmark::State& state) { construct(state, sines_text(state.range(0))); }
BENCHMARK(BM_Construct_Ones)
    ->RangeMultiplier(4)
    ->Range(1 << 10, 1 << 16)
    ->Unit(benchmark::kMillisecond)
    ->Complexity(benchmark::oN);
BENCHMARK(BM_Construct_Sines)
    ->RangeMultiplier(4)
    ->Range(1 << 10, 1 << 16)
    ->Unit(benchmark::kMillisecond)
    ->Complexity(benchmark::oN);

// Many short repetitions, randomly interleaved (see main): the median is the headline number,
// the minimum is the least disturbed run (useful on a loaded machine).
constexpr int kRepetitions = 25;
double minimum(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
#define RD_BENCH(fn)                                                          \
  BENCHMARK(fn)                                                               \
      ->Repetitions(kRepetitions)                                             \
      ->MinTime(0.05)                                                         \
      ->ComputeStatistics("min", minimum)                                     \
      ->ReportAggregatesOnly(true)
RD_BENCH(BM_Phi1_Hand);
RD_BENCH(BM_Phi1_Tape);
RD_BENCH(BM_Phi1_TapeGeneric);
RD_BENCH(BM_Phi2_Hand);
RD_BENCH(BM_Phi2_Tape);

/// Console output plus the medians, for the ratio summary.
class MedianReporter : public benchmark::ConsoleReporter {
 public:
  std::map<std::string, std::pair<double, double>> medians;  // real, CPU
  std::map<std::string, std::pair<double, double>> minima;   // real, CPU
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Aggregate) continue;
      if (r.aggregate_name == "median")
        medians[r.run_name.function_name] = {r.GetAdjustedRealTime(), r.GetAdjustedCPUTime()};
      if (r.aggregate_name == "min")
        minima[r.run_name.function_name] = {r.GetAdjustedRealTime(), r.GetAdjustedCPUTime()};
    }
    ConsoleReporter::ReportRuns(runs);
  }
};

/// Both sides must compute the same numbers before their speed is compared.
bool check_same_outputs() {
  bool ok = true;
  auto compare = [&](const char* name, const refdyn::Expression& e, auto hand, const auto& pts) {
    for (const auto& p : pts) {
      double v1, g1[2], H1[4], v2, g2[2], H2[4];
      e.evaluate(p.data(), v1, g1, H1);
      hand(p.data(), v2, g2, H2);
      auto close = [](double a, double b) {
        return std::fabs(a - b) <= 1e-12 * (1.0 + std::fabs(a) + std::fabs(b));
      };
      bool same = close(v1, v2);
      for (int k = 0; k < 2; ++k) same = same && close(g1[k], g2[k]);
      for (int k = 0; k < 4; ++k) same = same && close(H1[k], H2[k]);
      if (!same) {
        std::fprintf(stderr, "%s: tape and hand-written outputs differ at (%g, %g)\n", name, p[0],
                     p[1]);
        ok = false;
        return;
      }
    }
  };
  compare("Phi1", phi1(), phi1_hand, kPhi1Points);
  compare("Phi1 generic", phi1_generic(), phi1_hand, kPhi1Points);
  compare("Phi2", phi2(), phi2_hand, kPhi2Points);
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  if (!check_same_outputs()) return 1;
  std::printf("Phi1 tape: %d instructions, %d registers\n%s", phi1().tape_size(),
              phi1().register_count(), phi1().tape_listing().c_str());
  std::printf("Phi1 uses the quadratic kernel: %s\n", phi1().is_quadratic() ? "yes" : "no");
  std::printf("Phi2 tape: %d instructions, %d registers\n%s", phi2().tape_size(),
              phi2().register_count(), phi2().tape_listing().c_str());
  // Interleave the repetitions of all benchmarks (hand-written and tape runs then see the same
  // machine load); pass --benchmark_enable_random_interleaving=false to turn it off.
  std::vector<char*> args(argv, argv + argc);
  std::string interleave = "--benchmark_enable_random_interleaving=true";
  bool user_set = false;
  for (int i = 1; i < argc; ++i)
    user_set = user_set || std::string(argv[i]).find("random_interleaving") != std::string::npos;
  if (!user_set) args.insert(args.begin() + 1, interleave.data());
  argc = static_cast<int>(args.size());
  argv = args.data();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  MedianReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  std::printf("\nns per value+gradient+Hessian (real / CPU time); target ratio tape/hand <= 2\n");
  auto line = [&](const char* label, const std::string& tape, const std::string& hand) {
    for (auto* table : {&reporter.medians, &reporter.minima}) {
      auto h = table->find(hand);
      auto t = table->find(tape);
      if (h == table->end() || t == table->end()) continue;
      std::printf("  %-24s %-6s hand %6.2f / %6.2f   tape %6.2f / %6.2f   ratio %5.2f / %5.2f\n",
                  label, table == &reporter.medians ? "median" : "min", h->second.first,
                  h->second.second, t->second.first, t->second.second,
                  t->second.first / h->second.first, t->second.second / h->second.second);
    }
  };
  line("Phi1 (quadratic kernel)", "BM_Phi1_Tape", "BM_Phi1_Hand");
  line("Phi1 (generic tape)", "BM_Phi1_TapeGeneric", "BM_Phi1_Hand");
  line("Phi2 (tape)", "BM_Phi2_Tape", "BM_Phi2_Hand");
  return 0;
}
