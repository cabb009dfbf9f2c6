// The C++ side of bench/python_overhead.py: the same work as refdyn.run(problem).plan from
// Python — io::run_problem on a loaded Problem, the trajectory table of the plan, and the
// destruction of both — timed per repetition. Prints per line: wall time [s], CPU time of the
// thread [s] (less sensitive to a shared machine), table cells.
// Usage: refdyn_plan_timing SCENARIO.yaml REPETITIONS
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>

static double thread_cpu() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SCENARIO.yaml REPETITIONS\n", argv[0]);
    return 2;
  }
  const auto problem = refdyn::io::load_problem(argv[1]);
  const int reps = std::atoi(argv[2]);
  for (int i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = thread_cpu();
    size_t cells = 0;
    {
      const refdyn::io::Results r = refdyn::io::run_problem(*problem);
      const refdyn::io::CsvTable table = refdyn::io::trajectory_table(r.plan);
      cells = table.rows.size() * table.header.size();
    }
    const double c = thread_cpu() - c0;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%.9f %.9f %zu\n", s, c, cells);
  }
  return 0;
}
