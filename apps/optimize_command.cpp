// refdyn optimize FILE -o DIR: the scenario's optimize: section solved with NLopt
// (optimize/optimize.hpp, docs/optimize.md); the optimum written as `refdyn plan` writes a plan.
#include "commands.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/optimize/optimize.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace refdyn::app {

namespace fs = std::filesystem;

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_sigint(int) { g_stop = true; }

/// Installs on_sigint for the lifetime of the object (the previous handler back afterwards).
struct SigintGuard {
  SigintGuard() { previous = std::signal(SIGINT, on_sigint); }
  ~SigintGuard() { std::signal(SIGINT, previous); }
  void (*previous)(int) = SIG_DFL;
};

}  // namespace

int run_optimize(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
                 const std::string& method, long budget) {
  // wall_time_s is the whole command's; phases_s says where it went (docs/optimize.md)
  const auto command_start = std::chrono::steady_clock::now();
  auto lap = [last = command_start]() mutable {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - last).count();
    last = now;
    return s;
  };
  const std::string text = io::read_text_file(file, "scenario file", in.max_input_bytes);
  const ScenarioSpec spec = io::parse_scenario(text, file, in.max_input_bytes);
  if (!spec.optimize)
    throw Error(file + ": optimize: missing (refdyn optimize needs an optimize: section; docs/optimize.md)");
  const double load_time = lap();
  // Everything is checked before anything is written: optimize_scenario builds the scenario and
  // checks the optimize: section (and --method) before its first plan, and throws on bad input.
  if (!method.empty()) try {
      (void)optimize_method(method);
    } catch (const Error& e) {
      throw Error(std::string("--method: ") + e.what());
    }
  OptimizeOptions o;
  o.method = method;
  o.budget = budget;
  o.stop = &g_stop;
  const bool tty = !quiet && ::isatty(STDERR_FILENO);
  const auto start = std::chrono::steady_clock::now();
  long feasible = 0;
  bool shown = false;
  o.progress = [&](const OptimizeEvaluation& e, long total) {
    feasible += e.feasible;
    if (!tty) return;
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (el < 1.0) return;
    const int w = 30, k = static_cast<int>(w * std::min(1.0, static_cast<double>(e.index + 1) / static_cast<double>(total)));
    std::fprintf(stderr, "\roptimize %ld/%ld plans [%s%s] %ld feasible, last objective %s   ", e.index + 1, total,
                 std::string(static_cast<size_t>(k), '#').c_str(), std::string(static_cast<size_t>(w - k), ' ').c_str(),
                 feasible, fmt(e.objective).c_str());
    shown = true;
  };
  OptimizeResult r;
  {
    g_stop = false;
    SigintGuard guard;
    r = optimize_scenario(spec, o);
  }
  if (shown) std::fprintf(stderr, "\r%s\r", std::string(90, ' ').c_str());
  OptimizeSummary& s = r.summary;
  (void)lap();
  s.phases.insert(s.phases.begin(), {"load", load_time});
  double written = 0;  // seconds spent writing outputs
  auto finish = [&] {  // the whole command's time, up to the write of summary.json
    s.phases.emplace_back("write", written + lap());
    s.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - command_start).count();
  };
  io::prepare_output_dir(out_dir);
  io::write_text_atomic(fs::path(out_dir) / "optimization.csv", optimization_csv(s));
  written = lap();
  if (!s.feasible) {
    finish();
    JsonValue summary = JsonValue::object();
    summary["scenario"] = spec.name;
    summary["file"] = file;
    summary["optimization"] = s.to_json();
    io::write_text_atomic(fs::path(out_dir) / "summary.json", json_text(summary, 2, 2) + "\n");
    std::string reason = s.evaluations == 0 ? "no candidate was planned" : "none of the " + std::to_string(s.evaluations) +
                                                                            " planned candidates is feasible";
    for (auto it = s.history.rbegin(); it != s.history.rend(); ++it)
      if (!it->ok) {
        reason += " (last failure: " + it->reason + ")";
        break;
      }
    std::fprintf(stderr, "refdyn: error: optimize: no feasible point found: %s; %s (every evaluation: %s)\n", reason.c_str(),
                 s.message.c_str(), (fs::path(out_dir) / "optimization.csv").c_str());
    return s.stopped ? 130 : kNumerical;
  }
  // The optimum, planned again and written as `refdyn plan` writes it.
  const auto problem = build_problem(r.best_spec);
  io::RunOptions ro;
  ro.track = false;
  const io::Results res = io::run_problem(*problem, ro);
  JsonValue summary = io::summary_json(*problem, res);
  const std::string optimized = optimized_yaml(text, spec.root, s.variables, s.best_x);
  s.phases.emplace_back("final_plan", lap());
  // as io::write_results (plan only), summary.json last: it holds the time of the others
  io::write_csv_atomic(fs::path(out_dir) / "plan.csv", io::trajectory_table(res.plan));
  io::write_text_atomic(fs::path(out_dir) / "feasibility.json", res.feasibility.json() + "\n");
  io::write_text_atomic(fs::path(out_dir) / "optimized.yaml", optimized);
  finish();
  summary["optimization"] = s.to_json();
  io::write_text_atomic(fs::path(out_dir) / "summary.json", json_text(summary, 2, 2) + "\n");
  if (!quiet) {
    std::printf("optimize '%s' (%s): %s, %ld plans, %.3f s\n", spec.name.c_str(), s.method.c_str(), s.status.c_str(),
                s.evaluations, s.wall_time);
    std::string phases;
    for (const auto& [name, seconds] : s.phases) phases += (phases.empty() ? "" : ", ") + name + " " + fmt(std::round(seconds * 1000) / 1000);
    std::printf("  time [s]: %s\n", phases.c_str());
    const size_t shown = s.variables.size() <= 12 ? s.variables.size() : 8;  // a long list: optimized.yaml has it
    for (size_t i = 0; i < shown; ++i) std::printf("  %s = %s\n", s.variables[i].c_str(), fmt(s.best_x[i]).c_str());
    if (shown < s.variables.size())
      std::printf("  … and %zu more variables (optimized.yaml)\n", s.variables.size() - shown);
    if (!s.message.empty()) std::printf("  %s\n", s.message.c_str());
    std::printf("  objective = %s (feasible)\nresults in %s (optimized.yaml, optimization.csv, plan.csv, feasibility.json, "
                "summary.json)\n", fmt(s.best_objective).c_str(), out_dir.c_str());
  }
  if (s.stopped) {
    std::fprintf(stderr, "refdyn: interrupted: the best feasible point so far is written to %s\n", out_dir.c_str());
    return 130;
  }
  return kOk;
}

}  // namespace refdyn::app
