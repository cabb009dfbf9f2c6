// The cost of forward sensitivities (symbolic/sensitivity.hpp, docs/optimize.md) against one
// plan of the same scenario: the paper's manipulator (3 DOF, 2 programmed rows, LuGre in every
// joint, a flexible drive), 5000 RK4 steps, with 1, 3 and 10 parameters (the drive's duration
// Td; + the height law's dz, Tz; + the three link masses, the drive's stiffness and damping, the
// ellipse's half-axis b and the column height h1). The target: sensitivities cost at most
// ~(1 + np) plans. The tapes are compiled at the first call (reported once, "first call"), later
// calls for the same scenario reuse them (an optimization's evaluations).
//   sensitivity_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/symbolic/sensitivity.hpp"

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

using namespace refdyn;

namespace {

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw Error("sensitivity_bench: '" + from + "' not found in examples/paper/paper.yaml");
  return text.replace(at, from.size(), to);
}

struct Paper {
  std::unique_ptr<Problem> problem;
  Plan plan;
  Paper() {
    std::ifstream f(std::string(REFDYN_SOURCE_DIR) + "/examples/paper/paper.yaml");
    std::stringstream s;
    s << f.rdbuf();
    std::string y = s.str();
    y = replaced(y, "  Tz: 5 ", "  Tz: 5\n  Td: 5\n  m1: 20\n  m2: 8\n  m3: 3\n  kd: 1e4\n  cd: 70 ");
    y = replaced(y, "mass: 20,", "mass: m1,");
    y = replaced(y, "mass: 8,", "mass: m2,");
    y = replaced(y, "mass: 3,", "mass: m3,");
    y = replaced(y, "stiffness: 1e4, damping: 70,", "stiffness: kd, damping: cd,");
    y = replaced(y, "rise: 2*pi, duration: 5", "rise: 2*pi, duration: Td");
    problem = build_problem(io::parse_scenario(y, "paper_parameters.yaml"));
    plan = plan_problem(*problem, *problem->make_planner());
  }
};

Paper& paper() {
  static Paper p;
  return p;
}

const std::vector<std::string> kParameters{"Td", "dz", "Tz", "m1", "m2", "m3", "kd", "cd", "b", "h1"};

void BM_Plan(benchmark::State& state) {
  Paper& p = paper();
  auto planner = p.problem->make_planner();
  for (auto _ : state) benchmark::DoNotOptimize(plan_problem(*p.problem, *planner));
}
BENCHMARK(BM_Plan)->Unit(benchmark::kMillisecond);

void BM_Sensitivity(benchmark::State& state) {
  Paper& p = paper();
  SensitivityOptions o;
  o.parameters.assign(kParameters.begin(), kParameters.begin() + state.range(0));
  const auto t0 = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(plan_sensitivity(*p.problem, p.plan, o));  // compiles the tapes (or reuses them)
  state.counters["first_call_ms"] = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (auto _ : state) benchmark::DoNotOptimize(plan_sensitivity(*p.problem, p.plan, o));
}
BENCHMARK(BM_Sensitivity)->Arg(1)->Arg(3)->Arg(10)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
