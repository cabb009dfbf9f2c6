#pragma once
/// Running a Problem and writing its results: the one path from a built scenario to the files
/// that `refdyn plan`, `refdyn track` and `refdyn paper` write.
///
///   Problem ──run_problem──▶ Results (Plan + feasibility + closed-loop runs, all Trajectories)
///           ──trajectory_table / summary_json──▶ write_results: plan.csv, track_<name>.csv,
///                                                feasibility.json, sweep.csv, summary.json
/// Experiments run on a pool of RunOptions::jobs threads (each run with its own reference
/// dynamics and controller, results bit-identical to one thread), or spread over MPI ranks
/// (RunOptions::shard, apps/mpi_run.cpp).

#include "refdyn/simulate/feasibility.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/common/fields.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/scenario/problem.hpp"

#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace refdyn::io {

/// Makes a progress callback for a run named `what` over [t0, t1] (or none).
using ProgressFactory = std::function<std::function<void(double)>(const std::string& what, double t0, double t1)>;

/// Per-run summary of a closed-loop run: what summary.json and sweep.csv report of it. Computed
/// right after the run (so that the run's trajectory need not be kept) and, being numbers and
/// short strings only, cheap to keep for 10,000 runs and to send between MPI ranks.
struct JointTracking {
  double e0 = 0, settle_time = 0, late_error = 0, peak_tau = 0;
};
struct RunSummary {
  IntegrationStatus status = IntegrationStatus::Success;
  std::string message;             ///< empty on success; else when and why the run stopped
  double t_end = 0;                ///< [s] last valid time
  long steps = 0;
  long saturated_samples = 0;
  double final_max_abs_error = 0;  ///< max_j |e_j| at t_end
  double peak_abs_tau = 0;         ///< max over joints and samples of |τ|
  std::vector<JointTracking> joints;  ///< tracking_metrics(·, 1e-3, late_from)
  /// Plants with material constraints (0 otherwise): the largest |Φ|, |c| of the material rows
  /// over the run's samples, and the start's correction onto them (max |δq|, max |δq̇|).
  double max_material_residual = 0, initial_correction_q = 0, initial_correction_qd = 0;
  double wall_time = 0;            ///< [s] (not in sweep.csv: it differs between executions)
  bool ok() const { return status == IntegrationStatus::Success; }
  /// The largest finite value of a per-joint metric (NaN when none): a run's settle time is
  /// that of its slowest joint.
  double max_over_joints(double JointTracking::*metric) const;
};

}  // namespace refdyn::io

namespace refdyn {
// The fields of a run (common/fields.hpp): summary.json "runs" and "statistics", sweep.csv
// (its per-joint columns <csv>_<joint>), the MPI payloads, the Python dicts.
template <>
struct Fields<io::JointTracking> {
  using S = io::JointTracking;
  static constexpr unsigned in = sink::All | sink::Stat;
  static constexpr auto list() {
    return std::make_tuple(field("e0", &S::e0, "m or rad", in),
                           field("settle_time", &S::settle_time, "s", in) | JsonKey{"settle_time_rel_1e-3"} |
                               CsvColumn{"settle"},
                           field("late_error", &S::late_error, "m or rad", in) |
                               JsonKey{"max_abs_error_after_{late}s"} | CsvColumn{"late"},
                           field("peak_tau", &S::peak_tau, "N or N m", in) | JsonKey{"peak_abs_tau"});
  }
};
template <>
struct Fields<io::RunSummary> {
  using S = io::RunSummary;
  static double max_e0(const S& s) { return s.max_over_joints(&io::JointTracking::e0); }
  static double max_settle(const S& s) { return s.max_over_joints(&io::JointTracking::settle_time); }
  static double max_late(const S& s) { return s.max_over_joints(&io::JointTracking::late_error); }
  static constexpr unsigned record = sink::Json | sink::Wire | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("status", &S::status, "", record),  // sweep.csv: "not_run" too (sweep_csv)
                           field("message", &S::message) | CsvColumn{nullptr, 2},
                           field("t_end", &S::t_end, "s"),
                           field("steps", &S::steps, "", sink::Wire | sink::Python),
                           field("saturated_samples", &S::saturated_samples) | CsvColumn{nullptr, 1},
                           field("final_max_abs_error", &S::final_max_abs_error, "m or rad", sink::All | sink::Stat),
                           field("peak_abs_tau", &S::peak_abs_tau, "N or N m", sink::All | sink::Stat),
                           derived("max_e0", &max_e0, "m or rad", sink::Csv | sink::Stat),
                           derived("max_settle_time", &max_settle, "s", sink::Csv | sink::Stat) |
                               JsonKey{"max_settle_time_rel_1e-3"},
                           derived("max_late_error", &max_late, "m or rad", sink::Csv | sink::Stat) |
                               JsonKey{"max_max_abs_error_after_{late}s"},
                           field("joints", &S::joints) | CsvColumn{nullptr, 1} | Label{"joint"},
                           // sweep.csv has them as columns only when the plant has material rows (sweep_csv)
                           field("max_material_residual", &S::max_material_residual, "m or rad", record),
                           field("initial_correction_q", &S::initial_correction_q, "m or rad", record),
                           field("initial_correction_qd", &S::initial_correction_qd, "m/s or rad/s", record),
                           field("wall_time", &S::wall_time, "s", record) | JsonKey{"wall_time_s"});
  }
};
}  // namespace refdyn

namespace refdyn::io {

struct RunOptions {
  bool track = false;          ///< also run the experiments
  ProgressFactory progress;    ///< optional; the plan, and the run when there is just one
  /// Threads running experiments: 0 = every core (std::thread::hardware_concurrency). Each run
  /// has its own planner and controller; results do not depend on this number.
  int jobs = 1;
  /// Keep the trajectories of the first `keep_trajectories` runs (experiment order) in
  /// Results::runs[i].result: the report, the paper table and the Python bindings use them. The
  /// other runs keep only their RunSummary (bounded memory for sweeps of thousands of runs).
  size_t keep_trajectories = std::numeric_limits<size_t>::max();
  /// Non-empty: each run's table is written to <run_csv_dir>/track_<name>.csv as soon as the run
  /// ends (the folder must exist: io::prepare_output_dir).
  std::filesystem::path run_csv_dir;
  /// Distributed runs (MPI, apps/mpi_run.cpp): this process runs the experiments i with
  /// i % num_shards == shard; the others' RunRecord::done stays false.
  int shard = 0, num_shards = 1;
  /// Called after each run of this process ends (serialized: never two at once), with the number
  /// of runs ended so far and this process's total.
  std::function<void(size_t done, size_t total, const std::string& name)> on_run_done;
};

struct RunRecord {
  const Experiment* experiment = nullptr;
  bool done = false;           ///< run here (or filled in from another MPI rank)
  RunSummary summary;
  ClosedLoopResult result;     ///< empty (no joints) unless kept (RunOptions::keep_trajectories)
};

struct Results {
  std::unique_ptr<Planner> planner;  ///< the plan's (Problem::make_planner)
  /// The coordinate partition at t0 (partition_at_t0), recorded for summary.json and the report;
  /// none for a jerk problem or when the derivative at t0 failed.
  std::optional<PlannerPartition> partition_t0;
  Plan plan;
  FeasibilityReport feasibility;
  std::vector<RunRecord> runs;  ///< one per experiment of the Problem, in its order (if tracked)
  double wall_time = 0;        ///< [s], plan and runs
  bool runs_written = false;   ///< the runs' track_<name>.csv were streamed (RunOptions::run_csv_dir)
  /// The plan and every run reached their end.
  bool ok() const;
};

/// Calls body(i) for every i < count with i % num_shards == shard, on `jobs` threads (0: every
/// core) taking the indices in order from a shared counter; after(done, total, i) follows each
/// body, never two at once. After a body throws no new index starts, and the exception of the
/// smallest failed index is rethrown. The pool of run_problem (experiments) and run_variants.
void for_each_index(size_t count, int shard, int num_shards, int jobs, const std::function<void(size_t)>& body,
                    const std::function<void(size_t done, size_t total, size_t index)>& after = {});

/// Plans the problem (and, with options.track, runs its experiments) and assesses feasibility
/// from the recorded actuator efforts.
Results run_problem(const Problem& problem, const RunOptions& options = {});

/// The coordinate partition at (t0, x0) and its κ = cond(K_dc) = ‖A‖₁ ‖K_dc⁻¹‖₁, as the
/// projection solver takes it, whatever the problem's solver: a fresh reference dynamics with the
/// problem's options but `solver: projection`, evaluated once at the initial state. The Lagrange
/// (KKT) solver uses no partition, so the partition of its plan is the one the projection solver
/// would take (and the initial projection's dependent coordinates); `refdyn check`, summary.json
/// and the report all show this one. None for a jerk problem (no partition) or when the
/// projection fails at t0.
std::optional<PlannerPartition> partition_at_t0(const Problem& problem);

/// The solver the problem's reference dynamics use (Automatic resolved): projection or lagrange.
ReferenceSolver resolved_solver(const Problem& problem);
/// Whether that solver's solve uses the partition: the projection solver where it solves with the
/// partitioned basis or K_dc⁻¹ (projection_uses_partition: 2–4 coordinates, or as many rows as
/// coordinates); not its orthonormal basis (every other size), not the Lagrange solver.
inline bool solver_uses_partition(const Problem& problem) {
  return resolved_solver(problem) == ReferenceSolver::Projection &&
         projection_uses_partition(problem.model.nq, problem.constraints.rows());
}

/// One table for any Trajectory: the columns of the series it has, in a fixed order
///   t, q_*, qd_*, qdd_*, qref_*, e_*, tau_*, <force states (plans)>, <point>_x|y|z,
///   <recorded targets>, phi_*, phid_*, <force signals>, Qc_*, required_*, reaction_*, lambda_*
/// (required_ = actuator effort; reaction_ only when there are material constraints).
CsvTable trajectory_table(const Trajectory& trajectory);

/// Per joint of a closed-loop run: e0 = |e(t0)|, the time after which |e| stays below
/// settle_fraction·e0, the largest |e| for t >= late_from, and the peak |τ|.
std::vector<JointTracking> tracking_metrics(const ClosedLoopResult& r, double settle_fraction, double late_from);

/// The RunSummary of a run of `problem` (metrics with settle fraction 1e-3, late error after the
/// middle of the integration span).
RunSummary summarize_run(const Problem& problem, const ClosedLoopResult& run);

/// Percentiles (linear interpolation between order statistics, numpy's default) and mean of
/// the finite values of `v`; count = number of finite values, missing = the others.
struct Distribution {
  long count = 0, missing = 0;
  double min = 0, p5 = 0, p25 = 0, p50 = 0, p75 = 0, p95 = 0, p99 = 0, max = 0, mean = 0;
};
Distribution distribution_of(std::vector<double> v);
/// {count, missing, min, p5, …, max, mean} (null for NaN).
JsonValue distribution_json(const Distribution& d);

/// sweep.csv: one row per run (index, name, status, the sweep/grid/Monte Carlo values, t_end,
/// the summary metrics, per joint e0, settle time, late error, peak |τ|), no wall times, so that
/// it is the same file whatever the number of threads or ranks.
std::string sweep_csv(const Problem& problem, const Results& results);

/// summary.json: scenario, plan summary, feasibility, per run its status and metrics, and the
/// statistics over the runs ("statistics": Distribution of each metric, overall and per joint).
JsonValue summary_json(const Problem& problem, const Results& results);

/// Writes plan.csv, feasibility.json, sweep.csv (when runs were tracked), summary.json (last) and
/// track_<name>.csv of every run with a kept trajectory into `dir` (created if needed), each file
/// atomically.
void write_results(const std::filesystem::path& dir, const Problem& problem, const Results& results,
                   const JsonValue& summary);

}  // namespace refdyn::io
