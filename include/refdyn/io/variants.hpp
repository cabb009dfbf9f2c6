#pragma once
/// A family of tasks: the scenario's `variants:` section sets some of its parameters to other
/// values (a sweep, a grid or Monte Carlo samples, docs/sweeps.md), and each variant is a
/// scenario of its own — its own model, constraints, plan and experiments. run_variants plans
/// (and tracks) them on a thread pool, one variant per thread at a time, each into its own
/// folder, and keeps only a VariantSummary of each; variants_csv / variants_summary_json are
/// the aggregate.
///
///   ScenarioSpec ──expand_variants──▶ [Variant] ──variant_spec + build_problem + run_problem──▶
///   DIR/<variant>/{plan.csv, …} and VariantSummary ──▶ DIR/variants.csv, DIR/summary.json

#include "refdyn/io/results.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/scenario/spec.hpp"

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace refdyn::io {

struct Variant {
  std::string name;                                    ///< a file-safe folder name
  std::vector<std::pair<std::string, double>> values;  ///< parameter → value, in the order written
  long sample = -1;                                    ///< Monte Carlo sample index (−1: none)
};

/// The variants of `spec` (empty when it has no `variants:` section). Checks that every varied
/// parameter exists, names are unique and file-safe, and the count is at most limits.max_runs;
/// errors are "FILE:LINE: variants…: message".
std::vector<Variant> expand_variants(const ScenarioSpec& spec);

/// `spec` with the variant's parameters set to its values (parameters written after them, which
/// may use them, follow) and without the `variants:` section.
ScenarioSpec variant_spec(const ScenarioSpec& spec, const Variant& variant);

/// What is kept of a variant after its run: the plan's outcome, its feasibility, and (tracked)
/// the worst of its runs.
struct VariantSummary {
  bool done = false;            ///< run here (or filled in from another MPI rank)
  std::string error;            ///< the variant is not a valid scenario (e.g. its initial state violates a constraint)
  IntegrationStatus status = IntegrationStatus::Success;  ///< the plan's
  std::string message;
  double t_end = 0, max_constraint_residual = 0;
  bool feasible = false;
  long violations = 0;
  std::vector<double> peak_speed, peak_effort;  ///< per joint, over the plan
  long runs = 0, runs_completed = 0;            ///< tracked runs
  double worst_final_error = 0, worst_peak_tau = 0;
  double wall_time = 0;
  bool ok() const { return done && error.empty() && status == IntegrationStatus::Success && runs_completed == runs; }
};

}  // namespace refdyn::io

namespace refdyn {
// The fields of a variant (common/fields.hpp): summary.json "variants", variants.csv (per-joint
// columns <name>_<joint>), the MPI payloads. `done` is not sent: a received record is done;
// status and error are written as one status ("invalid", "not_run", the plan's) by the writers.
template <>
struct Fields<io::VariantSummary> {
  using S = io::VariantSummary;
  static constexpr unsigned record = sink::Wire | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("error", &S::error, "", record),
                           field("status", &S::status, "", record),
                           field("message", &S::message, "", sink::Json | record),
                           field("t_end", &S::t_end, "s") | ValidIf{when::Ran},
                           field("max_constraint_residual", &S::max_constraint_residual, "m or rad") | ValidIf{when::Ran},
                           field("feasible", &S::feasible) | ValidIf{when::Ran},
                           field("violations", &S::violations) | ValidIf{when::Ran},
                           field("peak_speed", &S::peak_speed, "m/s or rad/s", sink::Csv | record),
                           field("peak_effort", &S::peak_effort, "N or N m", sink::Csv | record),
                           field("runs", &S::runs) | OnlyIf{when::Tracked},
                           field("runs_completed", &S::runs_completed) | OnlyIf{when::Tracked},
                           field("worst_final_error", &S::worst_final_error, "m or rad") |
                               JsonKey{"worst_final_max_abs_error"} | CsvColumn{"worst_final_max_abs_error"} |
                               OnlyIf{when::Tracked} | ValidIf{when::Ran | when::HasRuns},
                           field("worst_peak_tau", &S::worst_peak_tau, "N or N m") | JsonKey{"worst_peak_abs_tau"} |
                               CsvColumn{"worst_peak_abs_tau"} | OnlyIf{when::Tracked} |
                               ValidIf{when::Ran | when::HasRuns},
                           field("wall_time", &S::wall_time, "s", sink::Json | record) | JsonKey{"wall_time_s"});
  }
};
}  // namespace refdyn

namespace refdyn::io {

struct VariantOptions {
  bool track = false;
  int jobs = 1;                      ///< threads (0: every core); each runs one variant at a time
  int shard = 0, num_shards = 1;     ///< MPI: this process runs the variants i % num_shards == shard
  /// Non-empty: every variant's results go to <dir>/<name>/ (plan.csv, …, as `refdyn plan/track`).
  std::filesystem::path dir;
  std::function<void(size_t done, size_t total, const std::string& name)> on_done;  ///< serialized
};

/// Builds, plans (and tracks) every variant of this shard. A variant that is not a valid
/// scenario is a VariantSummary with `error` set (the others still run); joints: the base
/// scenario's joint names (every variant has the same model structure).
std::vector<VariantSummary> run_variants(const ScenarioSpec& spec, const std::vector<Variant>& variants,
                                         const VariantOptions& options);

/// variants.csv: one row per variant (index, name, status, the parameter values, t_end, max |Φ|,
/// feasible, violations, per joint peak |q̇| and peak effort, and with runs: runs, completed,
/// worst final |e|, worst peak |τ|). No wall times.
std::string variants_csv(const std::vector<std::string>& joints, const std::vector<Variant>& variants,
                         const std::vector<VariantSummary>& summaries, bool tracked);

/// summary.json of a family: scenario, per variant its values and outcome, and statistics
/// (distribution_of) of the peak speeds and efforts per joint and the residuals.
JsonValue variants_summary_json(const std::string& scenario, const std::string& file,
                                const std::vector<std::string>& joints, const std::vector<Variant>& variants,
                                const std::vector<VariantSummary>& summaries, bool tracked, double wall_time);

}  // namespace refdyn::io
