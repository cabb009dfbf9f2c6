// refdyn check / plan / track / generate / kinds: thin clients of the library's pipeline
// (io::load_problem → io::run_problem → io::write_results).
#include "commands.hpp"
#include "mpi_run.hpp"
#include "report.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/fields_json.hpp"
#include "refdyn/io/check.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/sensitivity.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/io/variants.hpp"
#include "refdyn/optimize/optimize.hpp"
#include "refdyn/symbolic/symbolic.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/scenario/schema.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace refdyn::app {

namespace fs = std::filesystem;

namespace {

/// A progress bar on stderr for runs longer than a second (only on a terminal).
class Progress {
 public:
  Progress(std::string what, double t0, double t1, bool enabled = true)
      : what_(std::move(what)), t0_(t0), t1_(t1), start_(clock::now()) {
    tty_ = enabled && ::isatty(STDERR_FILENO);
  }
  void update(double t) {
    if (!tty_ || ++calls_ % 64) return;
    const double el = std::chrono::duration<double>(clock::now() - start_).count();
    if (el < 1.0) return;
    const double f = std::clamp((t - t0_) / (t1_ - t0_), 0.0, 1.0);
    const int w = 30, k = static_cast<int>(f * w);
    std::fprintf(stderr, "\r%s [%s%s] %3.0f%%  t = %.3f s", what_.c_str(), std::string(k, '#').c_str(),
                 std::string(w - k, ' ').c_str(), 100 * f, t);
    shown_ = true;
  }
  ~Progress() {
    if (shown_) std::fprintf(stderr, "\r%s\r", std::string(what_.size() + 60, ' ').c_str());
  }
 private:
  using clock = std::chrono::steady_clock;
  std::string what_;
  double t0_, t1_;
  clock::time_point start_;
  bool tty_ = false, shown_ = false;
  long calls_ = 0;
};

void print_plan(const Problem& p, const Plan& plan) {
  std::printf("scenario '%s': %d DOF, %d constraint rows; plan %s, %ld steps, t_end = %.6g s, max |Phi| = %.3g, %.3f s\n",
              p.name.c_str(), p.model.nq, p.constraints.rows(), to_string(plan.summary.status), plan.summary.steps,
              plan.summary.t_end, plan.summary.max_constraint_residual, plan.summary.wall_time);
  const IntegrationSummary& k = plan.summary;
  if (k.jacobian_evaluations > 0)
    std::printf("  bdf: %ld RHS and %ld Jacobian evaluations, %ld Newton iterations (%ld failed), %ld error-test "
                "failures\n", k.rhs_evaluations, k.jacobian_evaluations, k.newton_iterations, k.newton_failures,
                k.error_test_failures);
  if (k.projections > 0)
    std::printf("  projection: %ld steps corrected, largest correction %.3g\n", k.projections,
                k.max_projection_correction);
  if (!plan.summary.ok()) std::printf("  stopped: %s\n", plan.summary.message.c_str());
}

}  // namespace

namespace {
std::atomic<bool> g_error_output{true};
}  // namespace
void set_error_output(bool on) { g_error_output = on; }
bool error_output() { return g_error_output; }

/// The one-line report of a run that stopped early (printed even with -q).
void report_stopped(const io::Results& r) {
  if (!r.plan.summary.ok())
    std::fprintf(stderr, "refdyn: error: the plan stopped early: %s\n", r.plan.summary.message.c_str());
  size_t stopped = 0, on_stopped_plan = 0;
  for (const auto& run : r.runs)
    on_stopped_plan += run.summary.status == IntegrationStatus::ReferenceStopped;
  if (on_stopped_plan)  // one line for them all: they share the plan's end and reason
    std::fprintf(stderr,
                 "refdyn: error: %zu of %zu runs tracked the plan only up to where it stopped (t = %s s): none is a "
                 "success (status 'reference stopped early')\n",
                 on_stopped_plan, r.runs.size(), fmt(r.plan.summary.t_end).c_str());
  for (const auto& run : r.runs)
    if (!run.summary.ok() && run.summary.status != IntegrationStatus::ReferenceStopped && ++stopped <= kPrintedRuns)
      std::fprintf(stderr, "refdyn: error: experiment '%s' stopped early: %s\n", run.experiment->name.c_str(),
                   run.summary.message.c_str());
  if (stopped > kPrintedRuns)
    std::fprintf(stderr, "refdyn: error: %zu runs stopped early in all (each one's message: summary.json)\n", stopped);
}

io::ProgressFactory terminal_progress(bool enabled) {
  if (!enabled) return {};
  return [](const std::string& what, double t0, double t1) -> std::function<void(double)> {
    auto bar = std::make_shared<Progress>(what, t0, t1);
    return [bar](double t) { bar->update(t); };
  };
}

void check_optimize_section(const ScenarioSpec& spec) {
  if (!spec.optimize) return;
  (void)check_optimize(spec, *build_problem(spec));
}

int run_check(const std::string& file, const InputOptions& in, bool json) {
  const ScenarioSpec spec = io::load_scenario(file, in.max_input_bytes);
  // Everything is evaluated before anything is printed: "valid" is never followed by an error.
  const io::CheckReport report = io::check_scenario(spec, file);
  const std::string text = json ? json_text(to_json(report), 2) + "\n" : io::check_text(report);
  check_optimize_section(spec);
  std::cout << text;
  return kOk;
}

namespace {

/// Sweep progress on stderr (terminal only, after one second): runs ended, rate, ETA.
class SweepProgress {
 public:
  explicit SweepProgress(bool enabled, std::string noun = "runs")
      : tty_(enabled && ::isatty(STDERR_FILENO)), noun_(std::move(noun)), start_(clock::now()) {}
  void update(size_t done, size_t total) {
    if (!tty_) return;
    if (done == total) {  // the last one: the summary follows on a clean line
      clear();
      return;
    }
    const auto now = clock::now();
    const double el = std::chrono::duration<double>(now - start_).count();
    if (el < 1.0 || std::chrono::duration<double>(now - last_).count() < 0.2) return;
    last_ = now;
    const double f = static_cast<double>(done) / static_cast<double>(total), rate = static_cast<double>(done) / el;
    const int w = 30, k = static_cast<int>(f * w);
    const double eta = rate > 0 ? static_cast<double>(total - done) / rate : 0;
    std::fprintf(stderr, "\r%s %zu/%zu [%s%s] %3.0f%%  %.3g/s  ETA %s   ", noun_.c_str(), done, total,
                 std::string(k, '#').c_str(), std::string(w - k, ' ').c_str(), 100 * f, rate, duration_text(eta).c_str());
    shown_ = true;
  }
  ~SweepProgress() { clear(); }
  void clear() {
    if (shown_) std::fprintf(stderr, "\r%s\r", std::string(90, ' ').c_str());
    shown_ = false;
  }

 private:
  static std::string duration_text(double s) {
    char b[32];
    if (s < 60) std::snprintf(b, sizeof b, "%.0f s", s);
    else if (s < 3600) std::snprintf(b, sizeof b, "%dm%02ds", static_cast<int>(s / 60), static_cast<int>(s) % 60);
    else std::snprintf(b, sizeof b, "%dh%02dm", static_cast<int>(s / 3600), static_cast<int>(s / 60) % 60);
    return b;
  }
  using clock = std::chrono::steady_clock;
  bool tty_, shown_ = false;
  std::string noun_;
  clock::time_point start_, last_;
};

void print_runs(const Problem& p, const io::Results& r, const std::string& out_dir, bool report) {
  print_plan(p, r.plan);
  const size_t shown = r.runs.size() <= 2 * kPrintedRuns ? r.runs.size() : kPrintedRuns;
  for (size_t i = 0; i < shown; ++i) {
    const io::RunSummary& s = r.runs[i].summary;
    std::printf("  %-24s %s, final max |e| = %.3g, peak |tau| = %.4g%s\n", r.runs[i].experiment->name.c_str(),
                to_string(s.status), s.final_max_abs_error, s.peak_abs_tau, s.ok() ? "" : (" (" + s.message + ")").c_str());
  }
  if (shown < r.runs.size()) {
    long ok = 0;
    for (const auto& run : r.runs) ok += run.summary.ok();
    std::printf("  ... %zu runs in all, %ld reached the end (every run: sweep.csv; statistics: summary.json)\n",
                r.runs.size(), ok);
  }
  std::cout << r.feasibility.text() << "results in " << out_dir << (report ? " (report.html)" : "") << "\n";
}

/// "a, b,c" → {"a", "b", "c"}; an empty name is an error.
std::vector<std::string> split_names(const std::string& text) {
  std::vector<std::string> out;
  std::string rest = text;
  while (true) {
    const auto comma = rest.find(',');
    std::string name = rest.substr(0, comma);
    name.erase(0, name.find_first_not_of(" \t"));
    name.erase(name.find_last_not_of(" \t") + 1);
    if (name.empty()) throw Error("--sensitivity: expected parameter names separated by commas, got '" + text + "'");
    out.push_back(name);
    if (comma == std::string::npos) break;
    rest = rest.substr(comma + 1);
  }
  return out;
}

/// sensitivity.csv and sensitivity.json of a plan that reached its end (else one line on stderr).
void write_sensitivity(const Problem& problem, const Plan& plan, const SensitivityOptions& options,
                       const std::string& out_dir, bool quiet) {
  if (!plan.summary.ok()) {
    std::fprintf(stderr, "refdyn: error: no sensitivities: the plan stopped early\n");
    return;
  }
  const PlanSensitivity s = plan_sensitivity(problem, plan, options);
  const std::vector<Metric> metrics = plan_metrics(problem.model, plan, problem.residual_from);
  const Eigen::MatrixXd G = metric_gradients(problem, plan, s, metrics);
  io::write_csv_atomic(fs::path(out_dir) / "sensitivity.csv", io::sensitivity_table(problem, plan, s));
  io::write_text_atomic(fs::path(out_dir) / "sensitivity.json",
                        json_text(io::sensitivity_json(problem, s, metrics, G), 2, 3) + "\n");
  if (!quiet)
    std::printf("sensitivities to %zu parameter%s in %.3f s: sensitivity.csv, sensitivity.json\n", options.parameters.size(),
                options.parameters.size() == 1 ? "" : "s", s.seconds);
}

/// Why a plan is not feasible, in a few words: "2 violations: j1 effort, j3 velocity" or the
/// reason the verdict is incomplete.
std::string infeasibility_text(const FeasibilityReport& f) {
  if (!f.complete) return "verdict incomplete: " + f.incomplete_reason;
  std::string s = std::to_string(f.violations.size()) + (f.violations.size() == 1 ? " violation:" : " violations:");
  for (size_t i = 0; i < f.violations.size() && i < 4; ++i)
    s += (i ? ", " : " ") + f.violations[i].joint + " " + f.violations[i].quantity;
  if (f.violations.size() > 4) s += ", …";
  return s;
}

int plan_or_track(const std::string& file, const std::string& out_dir, bool quiet, bool track, const InputOptions& in,
                  const RunConfig& cfg) {
  std::unique_ptr<MpiSession> mpi;
  if (cfg.mpi) {
    mpi = std::make_unique<MpiSession>();
    if (mpi->rank() != 0) quiet = true, set_error_output(false);  // rank 0 speaks for all
  }
  auto agree = [&](const std::function<void()>& step) {  // with MPI: every rank or none goes on
    if (!mpi) return step();
    std::string error;
    try {
      step();
    } catch (const std::exception& e) {
      error = e.what();
    }
    mpi->agree(error);
  };
  std::unique_ptr<Problem> problem;
  ScenarioSpec spec;
  std::vector<io::Variant> variants;
  SensitivityOptions sensitivity;
  agree([&] {
    spec = io::load_scenario(file, in.max_input_bytes);
    problem = build_problem(spec);  // validates before anything is written
    variants = io::expand_variants(spec);
    if (spec.optimize) (void)check_optimize(spec, *problem);  // the whole file is valid or an error
    if (track && problem->experiments.empty())
      throw Error(file + ": experiments: " + (spec.experiments_value ? "an empty list" : "missing") +
                  " (track needs at least one experiment; see docs/scenario.md)");
    if (!variants.empty() && cfg.report)
      throw Error("--report: not for a family of variants (hint: refdyn report DIR/<variant> --scenario FILE draws one)");
    if (!cfg.sensitivity.empty()) {
      if (!variants.empty())
        throw Error("--sensitivity: not for a family of variants (hint: plan one variant's scenario, or remove variants:)");
      if (mpi) throw Error("--sensitivity: not with --mpi (one plan: run it in one process)");
      sensitivity.parameters = split_names(cfg.sensitivity);
      check_sensitivity_request(*problem, sensitivity);
    }
  });
  if (cfg.run_csv != "all" && cfg.run_csv != "auto" && cfg.run_csv != "none")
    throw Error("--run-csv: expected auto, all or none, got '" + cfg.run_csv + "'");
  // Rank 0 writes the aggregate and returns the exit code, which every rank returns.
  auto finish = [&](const std::function<int()>& write) {
    if (!mpi) return write();
    int code = kOk;
    std::string error;
    if (mpi->rank() == 0) try {
        code = write();
      } catch (const std::exception& e) {
        error = e.what();
      }
    code = mpi->broadcast(error.empty() ? code : -1);
    if (code == -1) mpi->fail(mpi->rank() == 0 ? error : "rank 0 failed to write the results");
    return code;
  };
  if (!variants.empty()) {
    // A family of tasks: each variant planned (and tracked) into DIR/<variant>/ (up to
    // kRunCsvAutoLimit variants, or --run-csv all), the aggregate into DIR.
    const bool folders = cfg.run_csv == "all" || (cfg.run_csv == "auto" && variants.size() <= kRunCsvAutoLimit);
    agree([&] {
      if (!mpi || mpi->rank() == 0) io::prepare_output_dir(out_dir);
    });
    io::VariantOptions vo;
    vo.track = track;
    vo.jobs = cfg.jobs < 0 ? (mpi ? 1 : 0) : cfg.jobs;
    if (mpi) vo.shard = mpi->rank(), vo.num_shards = mpi->size();
    if (folders) vo.dir = out_dir;
    SweepProgress bar(!quiet, "variants");
    vo.on_done = [&bar](size_t done, size_t total, const std::string&) { bar.update(done, total); };
    const auto start = std::chrono::steady_clock::now();
    std::vector<io::VariantSummary> summaries;
    agree([&] { summaries = io::run_variants(spec, variants, vo); });
    if (mpi) mpi->gather_variants(summaries);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return finish([&] {
      const int code = finish_family(*problem, variants, summaries, out_dir, quiet, track, folders, wall);
      if (code != kOk || !cfg.require_feasible) return code;
      size_t infeasible = 0;
      for (const io::VariantSummary& s : summaries) infeasible += !s.feasible;
      if (infeasible == 0) return code;
      std::fprintf(stderr, "refdyn: %zu of %zu variants not feasible (variants.csv); exit %d (--require-feasible)\n",
                   infeasible, summaries.size(), static_cast<int>(kNumerical));
      return static_cast<int>(kNumerical);
    });
  }
  const size_t runs = track ? problem->experiments.size() : 0;
  const bool run_csv = cfg.run_csv == "all" || (cfg.run_csv == "auto" && runs <= kRunCsvAutoLimit);
  agree([&] {
    if (!mpi || mpi->rank() == 0) io::prepare_output_dir(out_dir);
  });
  io::RunOptions o;
  o.track = track;
  o.progress = terminal_progress(!quiet);
  o.jobs = cfg.jobs < 0 ? (mpi ? 1 : 0) : cfg.jobs;
  // The report draws the first runs, as `refdyn report DIR` would from their tables; under MPI
  // those runs are on several ranks, so rank 0 makes the report from the folder, as that does.
  o.keep_trajectories = cfg.report && run_csv && !mpi ? kReportMaxRuns : 0;
  if (run_csv) o.run_csv_dir = out_dir;
  if (mpi) o.shard = mpi->rank(), o.num_shards = mpi->size();
  SweepProgress bar(!quiet && runs > 1);
  if (runs > 1) o.on_run_done = [&bar](size_t done, size_t total, const std::string&) { bar.update(done, total); };
  io::Results r;
  agree([&] { r = io::run_problem(*problem, o); });
  if (mpi) mpi->gather_runs(r);
  if (!sensitivity.parameters.empty()) write_sensitivity(*problem, r.plan, sensitivity, out_dir, quiet);
  return finish([&] {
    const int code = finish_results(*problem, r, out_dir, quiet, cfg.report && !mpi, run_csv);
    if (mpi && cfg.report) run_report(out_dir, file, "", quiet, in);
    if (code != kOk || !cfg.require_feasible || r.feasibility.feasible()) return code;
    std::fprintf(stderr, "refdyn: the plan is not feasible (%s; feasibility.json); exit %d (--require-feasible)\n",
                 infeasibility_text(r.feasibility).c_str(), static_cast<int>(kNumerical));
    return static_cast<int>(kNumerical);
  });
}

}  // namespace

int finish_family(const Problem& base, const std::vector<io::Variant>& variants,
                  const std::vector<io::VariantSummary>& summaries, const std::string& out_dir, bool quiet, bool track,
                  bool folders, double wall_time) {
  const bool tracked = track && !base.experiments.empty();
  io::write_text_atomic(fs::path(out_dir) / "variants.csv",
                        io::variants_csv(base.model.joint_name, variants, summaries, tracked));
  JsonValue summary =
      io::variants_summary_json(base.name, base.file, base.model.joint_name, variants, summaries, tracked, wall_time);
  summary["variant_folders"] = folders;
  io::write_text_atomic(fs::path(out_dir) / "summary.json", json_text(summary, 2, 2) + "\n");
  size_t bad = 0, feasible = 0;
  for (size_t i = 0; i < summaries.size(); ++i) {
    const io::VariantSummary& s = summaries[i];
    feasible += s.ok() && s.feasible;
    if (s.ok()) continue;
    if (++bad <= kPrintedRuns)
      std::fprintf(stderr, "refdyn: error: variant '%s': %s\n", variants[i].name.c_str(),
                   (!s.error.empty() ? s.error : !s.message.empty() ? s.message : std::string("a tracking run stopped early")).c_str());
  }
  if (bad > kPrintedRuns) std::fprintf(stderr, "refdyn: error: %zu variants in all did not complete (summary.json)\n", bad);
  if (!quiet) {
    std::printf("scenario '%s': %zu variants, %zu complete, %zu feasible and complete; wall time %.3f s\n", base.name.c_str(),
                variants.size(), variants.size() - bad, feasible, wall_time);
    const size_t shown = variants.size() <= 2 * kPrintedRuns ? variants.size() : kPrintedRuns;
    for (size_t i = 0; i < shown; ++i) {
      const io::VariantSummary& s = summaries[i];
      double peak = 0;
      for (double x : s.peak_effort) peak = std::max(peak, x);
      std::printf("  %-24s %-10s %s, peak |effort| = %.4g\n", variants[i].name.c_str(),
                  s.error.empty() ? to_string(s.status) : "invalid", s.feasible ? "feasible" : "not feasible", peak);
    }
    if (shown < variants.size()) std::printf("  ... (every variant: variants.csv; statistics: summary.json)\n");
    std::printf("results in %s (variants.csv, summary.json%s)\n", out_dir.c_str(), folders ? ", one folder per variant" : "");
  }
  return bad ? kNumerical : kOk;
}

/// Writes the results (summary.json last) and the report, prints the summary; the exit code.
int finish_results(const Problem& problem, const io::Results& r, const std::string& out_dir, bool quiet, bool report,
                   bool run_csv) {
  JsonValue summary = io::summary_json(problem, r);
  if (!r.runs.empty()) summary["track_csv"] = run_csv;
  io::write_results(out_dir, problem, r, summary);
  if (report) write_report(out_dir, problem, r, summary, quiet);
  if (!quiet) print_runs(problem, r, out_dir, report);
  if (!r.ok()) {
    report_stopped(r);
    return kNumerical;
  }
  return kOk;
}

int run_plan(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
             const RunConfig& cfg) {
  return plan_or_track(file, out_dir, quiet, false, in, cfg);
}

int run_track(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
              const RunConfig& cfg) {
  return plan_or_track(file, out_dir, quiet, true, in, cfg);
}

int run_generate(const std::string& file, const std::string& out_dir, const std::string& formats,
                 const std::string& prefix, bool quiet, const InputOptions& in) {
  bool c = false, latex = false, json = false;
  std::string rest = formats;
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    const std::string f = rest.substr(0, comma);
    rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
    if (f == "c") c = true;
    else if (f == "latex") latex = true;
    else if (f == "json") json = true;
    else throw Error("--format: expected a comma-separated list of c, latex, json, got '" + f + "'");
  }
  if (!c && !latex && !json) throw Error("--format: expected at least one of c, latex, json");
  const auto problem = io::load_problem(file, in.max_input_bytes);
  SymbolicOptions opt;
  opt.prefix = prefix;
  const SymbolicReferenceDynamics g = generate_symbolic(*problem, opt);
  // Everything is formed before the first file is written: an error leaves the folder as it was.
  std::vector<std::pair<std::string, std::string>> files;
  if (c) {
    files.emplace_back("reference_dynamics.h", g.c_header());
    files.emplace_back("reference_dynamics.c", g.c_source());
  }
  if (latex) files.emplace_back("equations.tex", g.latex());
  if (json) files.emplace_back("reference_dynamics.json", g.json());
  io::prepare_output_dir(out_dir);
  for (const auto& [name, text] : files) io::write_text_atomic(std::filesystem::path(out_dir) / name, text);
  if (!quiet) {
    const SymbolicSummary& s = g.summary();
    std::printf("generated the reference dynamics of '%s': %d coordinates, %d constraint rows, %d force states, "
                "%d parameters in %.2f s\n",
                problem->name.c_str(), s.nq, s.constraints, s.nz, s.parameters, s.seconds);
    if (c) std::printf("C: prefix %s, %ld common subexpressions, %ld operations\n", g.prefix().c_str(), s.c_temporaries, s.c_operations);
    for (const auto& f : files) std::printf("  %s\n", (std::filesystem::path(out_dir) / f.first).c_str());
  }
  return kOk;
}

int run_kinds(bool sections) {
  std::cout << (sections ? schema::markdown() : registry_markdown());
  return kOk;
}

}  // namespace refdyn::app
