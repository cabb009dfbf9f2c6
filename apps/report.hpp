#pragma once
/// refdyn report: one self-contained HTML file (report.html) for a results folder — the
/// scenario summary, the feasibility verdict, interactive plots (dygraphs) and a 3D replay of
/// the mechanism (three.js), both libraries inlined from the Debian packages at build time
/// (docs/report.md). The data come from the results tables (plan.csv, track_<name>.csv),
/// summary.json and feasibility.json, decimated for plotting; the 3D replay's link frames and
/// points are computed here by forward kinematics of the scenario's model.

#include "commands.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/csv.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/scenario/problem.hpp"

#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace refdyn::app {

/// Largest number of samples per series in the plots and of frames in the 3D replay.
inline constexpr int kReportPlotPoints = 1000;
inline constexpr int kReportReplayFrames = 1000;
/// Runs drawn in a report (the first ones, in experiment order); the sweep statistics in it
/// cover every run (summary.json).
inline constexpr std::size_t kReportMaxRuns = 24;
/// The default budget of the URDF meshes inlined into a report [MB of base64 text]
/// (`refdyn report --mesh-budget`).
inline constexpr double kReportMeshBudgetMB = 24.0;

/// What a report is made of: the built scenario and its results as tables and JSON text.
struct ReportInput {
  const Problem* problem = nullptr;
  std::string summary_json;      ///< summary.json (text, embedded as is)
  std::string feasibility_json;  ///< feasibility.json (text, embedded as is)
  io::CsvTable plan;             ///< plan.csv
  std::vector<std::pair<std::string, io::CsvTable>> runs;  ///< experiment name, track_<name>.csv
  /// optimization.csv of `refdyn optimize` (empty header: none): the report's optimization
  /// section (objective and constraint history).
  io::CsvText optimization;
  /// Largest size of the visual meshes inlined into the page [bytes, base64]; above it the replay
  /// draws the links as segments, as without meshes, and says so.
  double mesh_budget = kReportMeshBudgetMB * 1e6;
};

/// Throws refdyn::Error when refdyn was built without the report's JavaScript libraries
/// (checked before a run with --report, so that nothing is written then).
void require_report_template();

/// The HTML text. Throws refdyn::Error when the tables do not fit the scenario (e.g. no
/// q_<joint> column) or when refdyn was built without the JavaScript libraries. `notes`, when
/// given, receives what the page says about the model's meshes (not drawn, over the budget).
std::string report_html(const ReportInput& input, std::vector<std::string>* notes = nullptr);

/// `--report` on plan / track / paper: DIR/report.html from the results in memory; printed
/// (unless quiet): the notes of report_html.
void write_report(const std::filesystem::path& dir, const Problem& problem, const io::Results& results,
                  const JsonValue& summary, bool quiet);

/// `refdyn report DIR`: reads a results folder; the scenario is `scenario` when given, else the
/// one summary.json names (the built-in paper scenario for `refdyn paper` results).
/// mesh_budget_mb: ReportInput::mesh_budget in MB.
int run_report(const std::string& dir, const std::string& scenario, const std::string& output, bool quiet,
               const InputOptions& in, double mesh_budget_mb = kReportMeshBudgetMB);

}  // namespace refdyn::app
