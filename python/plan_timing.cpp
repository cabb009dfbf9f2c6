// The C++ side of bench/python_overhead.py: the same work as refdyn.run(problem).plan from
// Python — io::run_problem on a loaded Problem, the trajectory table of the plan, and the
// destruction of both — timed per repetition. Prints one wall time [s] per line.
// Usage: refdyn_plan_timing SCENARIO.yaml REPETITIONS
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SCENARIO.yaml REPETITIONS\n", argv[0]);
    return 2;
  }
  const auto problem = refdyn::io::load_problem(argv[1]);
  const int reps = std::atoi(argv[2]);
  for (int i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    size_t cells = 0;
    {
      const refdyn::io::Results r = refdyn::io::run_problem(*problem);
      const refdyn::io::CsvTable table = refdyn::io::trajectory_table(r.plan);
      cells = table.rows.size() * table.header.size();
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%.9f %zu\n", s, cells);
  }
  return 0;
}
