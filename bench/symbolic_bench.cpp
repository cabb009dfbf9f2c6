// refdyn generate: generation time for the paper's 3-DOF manipulator, the 7-DOF URDF arm and the
// test arms of tests/data/urdf (6 joints; 7 joints and a 2-finger hand; rounded π in their joint
// origins), and the generated C's ẋ = f(t, x) against the numeric engine
// (ReferenceDynamics::derivative) on the same problems, in the same run (target: ≤ 0.5).
//   build/bench/symbolic_bench
#include "bench_report.hpp"

#include "refdyn/io/scenario.hpp"
#include "refdyn/symbolic/symbolic.hpp"

#include "arm/reference_dynamics.h"
#include "arm6/reference_dynamics.h"
#include "arm7_hand/reference_dynamics.h"
#include "paper/reference_dynamics.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

namespace {

std::string example(const std::string& name) {
  if (name == "arm6" || name == "arm7_hand") return std::string(REFDYN_SOURCE_DIR) + "/tests/data/urdf/" + name + ".yaml";
  return std::string(REFDYN_SOURCE_DIR) + "/examples/" + name + "/" + name + ".yaml";
}

struct Case {
  std::unique_ptr<refdyn::Problem> problem;
  std::unique_ptr<refdyn::ReferenceDynamics> rd;
  Eigen::VectorXd x, xdot;
  double t = 0.7;
};

Case make_case(const std::string& name) {
  Case c;
  c.problem = refdyn::io::load_problem(example(name));
  c.rd = c.problem->make_reference_dynamics();
  c.x = c.rd->make_state(c.problem->q0, c.problem->qd0);
  for (int i = 0; i < c.problem->model.nq; ++i) c.x[c.problem->model.nq + i] += 0.1 * (i + 1);  // moving
  c.xdot.resize(c.x.size());
  return c;
}

void BM_Generate(benchmark::State& state, const std::string& name) {
  const auto problem = refdyn::io::load_problem(example(name));
  for (auto _ : state) {
    const refdyn::SymbolicReferenceDynamics g = refdyn::generate_symbolic(*problem);
    std::string c = g.c_source();
    benchmark::DoNotOptimize(c);
  }
}

void BM_Engine(benchmark::State& state, const std::string& name) {
  Case c = make_case(name);
  for (auto _ : state) {
    c.rd->derivative(c.t, c.x, c.xdot);
    benchmark::DoNotOptimize(c.xdot.data());
  }
}

template <typename Params, void (*Defaults)(Params*), int (*Rhs)(double, const double*, const Params*, double*)>
void BM_Generated(benchmark::State& state, const std::string& name) {
  Case c = make_case(name);
  Params p;
  Defaults(&p);
  for (auto _ : state) {
    benchmark::DoNotOptimize(Rhs(c.t, c.x.data(), &p, c.xdot.data()));
    benchmark::ClobberMemory();
  }
}

}  // namespace

int main(int argc, char** argv) {
  // One generation of each, timed once, with the sizes of the code it writes.
  for (const char* name : {"paper", "urdf_arm_line", "arm6", "arm7_hand"}) {
    const auto problem = refdyn::io::load_problem(example(name));
    const auto t0 = std::chrono::steady_clock::now();
    const refdyn::SymbolicReferenceDynamics g = refdyn::generate_symbolic(*problem);
    const std::string c = g.c_source();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%-14s %d DOF, %d constraint rows: generated in %.3f s (symbolic %.3f s), C %zu bytes, "
                "%ld operations, %ld CSE temporaries\n",
                name, g.summary().nq, g.summary().constraints, s, g.summary().seconds, c.size(),
                g.summary().c_operations, g.summary().c_temporaries);
  }
  benchmark::RegisterBenchmark("generate/paper_3dof", BM_Generate, std::string("paper"))
      ->Unit(benchmark::kMillisecond)->Iterations(3);
  benchmark::RegisterBenchmark("generate/arm_7dof", BM_Generate, std::string("urdf_arm_line"))
      ->Unit(benchmark::kMillisecond)->Iterations(1);
  benchmark::RegisterBenchmark("rhs_engine/paper_3dof", BM_Engine, std::string("paper"));
  benchmark::RegisterBenchmark("rhs_generated/paper_3dof",
                               BM_Generated<paper_params, paper_default_params, paper_rhs>, std::string("paper"));
  benchmark::RegisterBenchmark("rhs_engine/arm_7dof", BM_Engine, std::string("urdf_arm_line"));
  benchmark::RegisterBenchmark("rhs_generated/arm_7dof", BM_Generated<arm_params, arm_default_params, arm_rhs>,
                               std::string("urdf_arm_line"));
  benchmark::RegisterBenchmark("rhs_engine/arm6", BM_Engine, std::string("arm6"));
  benchmark::RegisterBenchmark("rhs_generated/arm6", BM_Generated<arm6_params, arm6_default_params, arm6_rhs>,
                               std::string("arm6"));
  benchmark::RegisterBenchmark("rhs_engine/arm7_hand", BM_Engine, std::string("arm7_hand"));
  benchmark::RegisterBenchmark("rhs_generated/arm7_hand",
                               BM_Generated<arm7_hand_params, arm7_hand_default_params, arm7_hand_rhs>,
                               std::string("arm7_hand"));
  if (!refdyn_bench::initialize_with_defaults(argc, argv)) return 1;
  refdyn_bench::Reporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  std::printf("\nmedians (CPU time per call) and ratio generated / engine, same run:\n");
  for (const char* m : {"paper_3dof", "arm_7dof", "arm6", "arm7_hand"}) {
    const double e = reporter.stats["rhs_engine/" + std::string(m)].median();
    const double g = reporter.stats["rhs_generated/" + std::string(m)].median();
    std::printf("  %-12s engine %10s   generated C %10s   ratio %s\n", m, refdyn_bench::fmt_ns(e).c_str(),
                refdyn_bench::fmt_ns(g).c_str(), refdyn_bench::fmt_ratio(g / e).c_str());
  }
  for (const char* m : {"paper_3dof", "arm_7dof"})
    std::printf("  generation %-12s %s\n", m, refdyn_bench::fmt_ns(reporter.stats["generate/" + std::string(m)].median()).c_str());
  return 0;
}
