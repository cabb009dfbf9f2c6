#pragma once
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/variants.hpp"

#include <cstddef>
#include <string>

namespace refdyn::app {

/// Exit codes of the refdyn command (documented in the README and `refdyn --help`).
enum ExitCode : int {
  kOk = 0,
  kUsage = 1,           ///< bad command line
  kBadInput = 2,        ///< invalid scenario, model or option: nothing was written
  kInternal = 3,        ///< a bug: please report
  kNumerical = 4,       ///< a run stopped early (divergence, singular partition): partial results written;
                        ///< also: no feasible point (optimize), a plan not feasible (plan --require-feasible)
};

/// Options shared by the commands that read a scenario.
struct InputOptions {
  std::size_t max_input_bytes = io::kDefaultMaxInputBytes;
};

/// How `track` (and `plan`) run: threads, per-run CSVs, MPI, report.
struct RunConfig {
  int jobs = -1;                 ///< threads for the experiments; 0: every core; -1: default (every core; 1 per rank with MPI)
  std::string run_csv = "auto";  ///< track_<name>.csv per run: all, none, auto (all up to kRunCsvAutoLimit runs)
  bool mpi = false;              ///< spread the runs over the MPI ranks (apps/mpi_run.hpp)
  bool report = false;           ///< also write report.html
  /// plan --sensitivity p1,p2: forward sensitivities of the plan (sensitivity.csv, .json)
  std::string sensitivity;
  /// plan --require-feasible: exit kNumerical (after writing the results) when the plan's
  /// feasibility verdict (feasibility.json) is not feasible, or, for variants, any variant's.
  bool require_feasible = false;
};
inline constexpr std::size_t kRunCsvAutoLimit = 100;
/// Runs listed one by one on the terminal (and stopped runs on stderr); the rest are in the files.
inline constexpr std::size_t kPrintedRuns = 20;

/// main() prints a caught error only when this is on (MPI ranks other than 0 stay silent).
void set_error_output(bool on);
bool error_output();

/// A progress bar on stderr (terminal only, after one second) for runs of the pipeline.
io::ProgressFactory terminal_progress(bool enabled);

/// One line on stderr per run that stopped early (printed even with -q).
void report_stopped(const io::Results& results);

/// `refdyn check`: the report as text, or as JSON (--json: Fields<io::CheckReport>).
int run_check(const std::string& file, const InputOptions& in, bool json = false);
/// The scenario's optimize: section checked (check_optimize; nothing when it has none), so that
/// check, plan and track reject a file that optimize would.
void check_optimize_section(const ScenarioSpec& spec);
/// refdyn optimize (apps/optimize_command.cpp): kOk; kNumerical when no feasible point was
/// found; 130 when interrupted (the best feasible point so far written).
int run_optimize(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
                 const std::string& method, long budget);
int run_plan(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
             const RunConfig& config);
int run_track(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in,
              const RunConfig& config);
/// A family of variants: writes variants.csv and summary.json (last) into out_dir, prints the
/// summary; kOk, or kNumerical when a variant is invalid or stopped early.
int finish_family(const Problem& base, const std::vector<io::Variant>& variants,
                  const std::vector<io::VariantSummary>& summaries, const std::string& out_dir, bool quiet, bool track,
                  bool folders, double wall_time);
/// Writes the results of a run (summary.json last) and the report, prints the summary (unless
/// quiet); returns kOk, or kNumerical when the plan or a run stopped early.
int finish_results(const Problem& problem, const io::Results& results, const std::string& out_dir, bool quiet,
                   bool report, bool run_csv_written);
int run_plot(const std::string& dir);
/// refdyn kinds: the registries' reference, or (sections) the scenario sections' key tables.
int run_kinds(bool sections);
int run_generate(const std::string& file, const std::string& out_dir, const std::string& formats,
                 const std::string& prefix, bool quiet, const InputOptions& in);

}  // namespace refdyn::app
