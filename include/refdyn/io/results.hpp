#pragma once
/// Running a Problem and writing its results: the one path from a built scenario to the files
/// that `refdyn plan`, `refdyn track` and `refdyn paper` write.
///
///   Problem ──run_problem──▶ Results (Plan + feasibility + closed-loop runs, all Trajectories)
///           ──trajectory_table / summary_json──▶ write_results: plan.csv, track_<name>.csv,
///                                                feasibility.json, summary.json

#include "refdyn/feasibility.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/json.hpp"
#include "refdyn/problem.hpp"

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace refdyn::io {

/// Makes a progress callback for a run named `what` over [t0, t1] (or none).
using ProgressFactory = std::function<std::function<void(double)>(const std::string& what, double t0, double t1)>;

struct RunOptions {
  bool track = false;          ///< also run the experiments
  ProgressFactory progress;    ///< optional
};

struct RunRecord {
  const Experiment* experiment = nullptr;
  ClosedLoopResult result;
};

struct Results {
  std::unique_ptr<ReferenceDynamics> rd;
  Plan plan;
  FeasibilityReport feasibility;
  std::vector<RunRecord> runs;
  double wall_time = 0;        ///< [s], plan and runs
  /// The plan and every run reached their end.
  bool ok() const;
};

/// Plans the problem (and, with options.track, runs its experiments) and assesses feasibility
/// from the recorded actuator efforts.
Results run_problem(const Problem& problem, const RunOptions& options = {});

/// One table for any Trajectory: the columns of the series it has, in a fixed order
///   t, q_*, qd_*, qdd_*, qref_*, e_*, tau_*, <force states (plans)>, <point>_x|y|z,
///   <recorded targets>, phi_*, phid_*, <force signals>, Qc_*, required_*, reaction_*, lambda_*
/// (required_ = actuator effort; reaction_ only when there are material constraints).
CsvTable trajectory_table(const Trajectory& trajectory);

/// Per joint of a closed-loop run: e0 = |e(t0)|, the time after which |e| stays below
/// settle_fraction·e0, the largest |e| for t >= late_from, and the peak |τ|.
struct JointTracking {
  double e0 = 0, settle_time = 0, late_error = 0, peak_tau = 0;
};
std::vector<JointTracking> tracking_metrics(const ClosedLoopResult& r, double settle_fraction, double late_from);

/// summary.json: scenario, plan summary, feasibility, and per run its status and metrics.
JsonValue summary_json(const Problem& problem, const Results& results);

/// Writes plan.csv, feasibility.json, summary.json and track_<name>.csv into `dir` (created if
/// needed), each file atomically.
void write_results(const std::filesystem::path& dir, const Problem& problem, const Results& results,
                   const JsonValue& summary);

}  // namespace refdyn::io
