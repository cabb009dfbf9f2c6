#pragma once
// Shared reporting for the benchmark executables: the console shows the median and min
// aggregates of Google Benchmark's repetitions, and every repetition's CPU time per call is
// collected so that each program can print its own median/min ratio table at the end.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace refdyn_bench {

struct Stats {
  std::vector<double> reps;  // per-repetition mean time per call [ns]
  double agg_median = NAN, agg_min = NAN;
  double median() const {
    if (reps.empty()) return agg_median;
    std::vector<double> v = reps;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  }
  double min() const { return reps.empty() ? agg_min : *std::min_element(reps.begin(), reps.end()); }
};

class Reporter : public benchmark::ConsoleReporter {
 public:
  std::map<std::string, Stats> stats;

  void ReportRuns(const std::vector<Run>& runs) override {
    std::vector<Run> shown;
    for (const Run& r : runs) {
      if (r.error_occurred) {
        shown.push_back(r);
        continue;
      }
      const std::string name = r.run_name.function_name;
      const double ns = r.GetAdjustedCPUTime() * to_ns(r.time_unit);
      if (r.run_type == Run::RT_Iteration) {
        stats[name].reps.push_back(ns);
        if (r.repetitions <= 1) shown.push_back(r);
      } else if (r.aggregate_name == "median" || r.aggregate_name == "min") {
        (r.aggregate_name == "median" ? stats[name].agg_median : stats[name].agg_min) = ns;
        shown.push_back(r);
      }
    }
    if (!shown.empty()) ConsoleReporter::ReportRuns(shown);
  }

 private:
  static double to_ns(benchmark::TimeUnit u) {
    switch (u) {
      case benchmark::kNanosecond: return 1.0;
      case benchmark::kMicrosecond: return 1e3;
      case benchmark::kMillisecond: return 1e6;
      case benchmark::kSecond: return 1e9;
    }
    return 1.0;
  }
};

inline std::string fmt_ns(double ns) {
  char buf[32];
  if (!std::isfinite(ns)) return "-";
  if (ns < 1e4) std::snprintf(buf, sizeof buf, "%.0f ns", ns);
  else if (ns < 1e6) std::snprintf(buf, sizeof buf, "%.1f us", ns / 1e3);
  else std::snprintf(buf, sizeof buf, "%.2f ms", ns / 1e6);
  return buf;
}
inline std::string fmt_ratio(double r) {
  char buf[32];
  if (!std::isfinite(r)) return "-";
  std::snprintf(buf, sizeof buf, r < 10 ? "%.2f" : (r < 100 ? "%.1f" : "%.0f"), r);
  return buf;
}

/// benchmark::Initialize with refdyn's defaults (10 repetitions, random interleaving with the
/// peer, min time 0.05 s); later command-line flags override them. False on unknown flags.
inline bool initialize_with_defaults(int argc, char** argv) {
  static char rep[] = "--benchmark_repetitions=10";
  static char inter[] = "--benchmark_enable_random_interleaving=true";
  static char mt[] = "--benchmark_min_time=0.05";
  static std::vector<char*> args;
  args = {argv[0], rep, inter, mt};
  for (int i = 1; i < argc; ++i) args.push_back(argv[i]);
  int nargs = static_cast<int>(args.size());
  benchmark::Initialize(&nargs, args.data());
  return !benchmark::ReportUnrecognizedArguments(nargs, args.data());
}

}  // namespace refdyn_bench
