// One closed-loop run on the four-bar (examples/four_bar): the plant as built (the loop closure
// kept, one motor at the crank, computed torque on the reduced dynamics) against the same run on
// the unconstrained plant (the open crank-coupler-rocker chain, a motor at every joint: what
// `refdyn track` simulated before material rows were kept). Same plan, same RK4 grid (2 s, 2001
// samples), the reference replayed from the plan's stages. Issue 32's target: ratio ≤ 2.
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/closed_loop.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <memory>

using namespace refdyn;

namespace {

struct FourBar {
  std::unique_ptr<Problem> p = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/examples/four_bar/four_bar.yaml");
  std::unique_ptr<Planner> planner = p->make_planner();
  Plan plan = plan_problem(*p, *planner);
};

FourBar& fb() {
  static FourBar f;
  return f;
}

void constrained(benchmark::State& st) {
  FourBar& f = fb();
  auto ctrl = f.p->experiments[0]->make_controller(f.p->model);
  ClosedLoopOptions o;
  o.integrator = f.p->integrator;
  o.material = f.p->material.get();
  o.plant = f.p->options;
  // The consistent start the scenario's run has.
  const ClosedLoopResult ref = track_experiment(*f.p, *f.p->experiments[0], f.plan, *f.planner);
  const Eigen::VectorXd x0 = ref.x.front();
  for (auto _ : st) {
    ClosedLoopResult r = simulate_closed_loop(f.p->model, ForceSet(), *ctrl, f.plan, nullptr, x0, o);
    if (!r.summary.ok()) st.SkipWithError(r.summary.message.c_str());
    benchmark::DoNotOptimize(r.x.back()[0]);
  }
}

void unconstrained(benchmark::State& st) {
  FourBar& f = fb();
  ComputedTorquePD ctrl(f.p->model, Eigen::Vector3d(10, 10, 10));
  ClosedLoopOptions o;
  o.integrator = f.p->integrator;
  const ClosedLoopResult ref = track_experiment(*f.p, *f.p->experiments[0], f.plan, *f.planner);
  const Eigen::VectorXd x0 = ref.x.front();
  for (auto _ : st) {
    ClosedLoopResult r = simulate_closed_loop(f.p->model, ForceSet(), ctrl, f.plan, nullptr, x0, o);
    if (!r.summary.ok()) st.SkipWithError(r.summary.message.c_str());
    benchmark::DoNotOptimize(r.x.back()[0]);
  }
}

}  // namespace

// Repetitions with the minimum beside the median: the minimum is the least disturbed run on a
// shared machine (bench/README.md).
double least(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
BENCHMARK(constrained)->Name("ClosedLoop/FourBar/constrained_plant_one_motor")->Unit(benchmark::kMillisecond)->Repetitions(15)->ComputeStatistics("min", least)->ReportAggregatesOnly(true);
BENCHMARK(unconstrained)->Name("ClosedLoop/FourBar/unconstrained_plant_all_motors")->Unit(benchmark::kMillisecond)->Repetitions(15)->ComputeStatistics("min", least)->ReportAggregatesOnly(true);
BENCHMARK_MAIN();
