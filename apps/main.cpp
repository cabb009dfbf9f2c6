// refdyn command line. Library errors (refdyn::Error) are caught once here, printed as one
// line, and mapped to the documented exit codes (commands.hpp).
#include "commands.hpp"
#include "paper_study_output.hpp"
#include "report.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/common/version.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>
#include <vector>

namespace {

/// The one-line form of a command-line error, with "did you mean" for a mistyped command.
std::string usage_message(const CLI::ParseError& e, int argc, char** argv, const std::vector<std::string>& commands) {
  std::string msg = e.what();
  for (char& ch : msg)
    if (ch == '\n') ch = ' ';
  if (argc > 1) {
    const std::string first = argv[1];
    bool known = first.empty() || first[0] == '-';
    for (const auto& c : commands) known = known || c == first;
    if (!known) msg = "unknown command '" + first + "'" + refdyn::did_you_mean(first, commands);
  }
  return msg + " (run 'refdyn --help')";
}


/// Every option of every command, filled in by CLI11.
struct Args {
  std::string file, out_dir = "results";
  bool quiet = false, report = false, sections = false, json = false;
  std::string scenario, report_out;
  std::string formats = "c,latex,json", prefix;
  refdyn::app::InputOptions in;
  refdyn::app::RunConfig run;
  std::string method;
  long budget = 0;
  double mesh_budget = refdyn::app::kReportMeshBudgetMB;
};

struct Commands {
  CLI::App *check, *plan, *optimize, *track, *plot, *paper, *report, *generate, *kinds;
};

const std::vector<std::string> kCommandNames{"check", "plan", "optimize", "track", "plot", "report", "paper", "generate", "kinds"};

void add_input_options(CLI::App* c, Args& a) {
  c->add_option("--max-input-size", a.in.max_input_bytes, "Largest scenario or URDF file read [bytes]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
}

void add_run_options(CLI::App* c, Args& a, const char* what) {
  c->add_option("-j,--jobs", a.run.jobs,
                std::string("Threads running ") + what + " (0: every core; default: every core, 1 per rank with --mpi); "
                "results do not depend on it")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--run-csv", a.run.run_csv,
                std::string("Per-run files (track_<name>.csv; for variants: a folder each): all, none, or auto (all up "
                            "to 100); the aggregate (sweep.csv / variants.csv, summary.json) always"))
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "all", "none"}));
  c->add_flag("--mpi", a.run.mpi,
              "Spread the runs or variants over MPI ranks (mpirun -np N refdyn ... --mpi; DIR on a shared file "
              "system); the files are those of one process (docs/sweeps.md)");
}

/// The output options plan, track and paper share.
void add_output_options(CLI::App* c, Args& a) {
  c->add_option("-o,--output", a.out_dir, "Output folder")->capture_default_str();
  c->add_flag("-q,--quiet", a.quiet, "Print nothing on success");
  c->add_flag("--report", a.report, "Also write report.html (interactive plots, 3D replay; docs/report.md)");
}

/// check, plan, track: the commands that read a scenario and solve it.
void add_scenario_commands(CLI::App& app, Args& a, Commands& c) {
  c.check = app.add_subcommand("check", "Validate a scenario and print its summary (DOF, constraints, partition, residuals)");
  c.check->add_option("file", a.file, "Scenario file (YAML)")->required();
  c.check->add_flag("--json", a.json,
                    "Print the report as JSON (the keys of Python's refdyn.check, without its text; docs/python.md)");
  add_input_options(c.check, a);

  c.plan = app.add_subcommand("plan", "Solve the reference dynamics: planned motion (CSV), feasibility report (JSON)");
  c.plan->add_option("file", a.file, "Scenario file (YAML)")->required();
  add_output_options(c.plan, a);
  add_input_options(c.plan, a);
  add_run_options(c.plan, a, "the scenario's variants");
  c.plan->add_option("--sensitivity", a.run.sensitivity,
                     "Also write the plan's forward sensitivities to the named parameters (comma-separated): "
                     "sensitivity.csv (per sample), sensitivity.json (metrics and their gradients; docs/sensitivity.md)");
  c.plan->add_flag("--require-feasible", a.run.require_feasible,
                   "Exit 4 (after writing the results) when the plan's feasibility verdict is not feasible "
                   "(feasibility.json; for variants: when any variant is not feasible)");

  c.optimize = app.add_subcommand(
      "optimize", "Choose task parameters (the scenario's optimize: section): optimized.yaml, optimization.csv, the optimum's plan");
  c.optimize->add_option("file", a.file, "Scenario file (YAML) with an optimize: section")->required();
  c.optimize->add_option("-o,--output", a.out_dir, "Output folder")->capture_default_str();
  c.optimize->add_flag("-q,--quiet", a.quiet, "Print nothing on success");
  c.optimize->add_option("--method", a.method, "slsqp | mma | cobyla | bobyqa | phase_plane (default: the scenario's optimize.method)");
  c.optimize->add_option("--budget", a.budget, "Most plan evaluations (default: the scenario's optimize.budget)")
      ->check(CLI::PositiveNumber);
  add_input_options(c.optimize, a);

  c.track = app.add_subcommand("track", "Plan, then run the scenario's closed-loop tracking experiments");
  c.track->add_option("file", a.file, "Scenario file (YAML)")->required();
  add_output_options(c.track, a);
  add_run_options(c.track, a, "experiments (or variants)");
  add_input_options(c.track, a);
}

/// plot, paper, report, generate, kinds.
void add_other_commands(CLI::App& app, Args& a, Commands& c) {
  c.plot = app.add_subcommand("plot", "Draw the figures (PNG + PDF) of a results folder");
  c.plot->add_option("dir", a.out_dir, "Results folder written by plan, track or paper")->required();

  c.paper = app.add_subcommand("paper", "Run the paper's three-link manipulator study (the main job)");
  add_output_options(c.paper, a);
  c.paper->add_option("-j,--jobs", a.run.jobs, "Threads running the four tracking runs (0 or default: every core)")
      ->check(CLI::NonNegativeNumber);

  c.report = app.add_subcommand(
      "report", "Write DIR/report.html: one self-contained HTML file with the summary, interactive plots and a 3D replay");
  c.report->add_option("dir", a.out_dir, "Results folder written by plan, track or paper")->required();
  c.report->add_option("--scenario", a.scenario,
                       "Scenario file of the results (default: the one summary.json names; built in for paper results)");
  c.report->add_option("-o,--output", a.report_out, "Report file (default: DIR/report.html)");
  c.report->add_flag("-q,--quiet", a.quiet, "Print nothing on success");
  c.report->add_option("--mesh-budget", a.mesh_budget,
                       "Largest size of the URDF's visual meshes inlined into the page [MB]; above it the 3D replay "
                       "draws the links as segments")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  add_input_options(c.report, a);

  c.generate = app.add_subcommand(
      "generate", "Generate the reference dynamics as equations and code: equations.tex, reference_dynamics.c/.h, .json");
  c.generate->add_option("file", a.file, "Scenario file (YAML)")->required();
  c.generate->add_option("-o,--output", a.out_dir, "Output folder")->capture_default_str();
  c.generate->add_option("--format", a.formats, "Comma-separated outputs: c, latex, json")->capture_default_str();
  c.generate->add_option("--prefix", a.prefix, "Prefix of the C identifiers (default: rd_<scenario name>_)");
  c.generate->add_flag("-q,--quiet", a.quiet, "Print nothing on success");
  add_input_options(c.generate, a);

  c.kinds = app.add_subcommand("kinds", "List the constraint kinds, force elements and controllers with their keys");
  c.kinds->add_flag("--sections", a.sections,
                    "List the keys of the scenario's sections instead (the tables of docs/scenario.md)");
}

/// Runs the chosen command; refdyn::Error and the rest are mapped to exit codes by the caller.
int dispatch(const Commands& c, Args& a) {
  using namespace refdyn::app;
  if (*c.check) return run_check(a.file, a.in, a.json);
  if (a.report) require_report_template();
  a.run.report = a.report;
  if (*c.plan) return run_plan(a.file, a.out_dir, a.quiet, a.in, a.run);
  if (*c.optimize) return run_optimize(a.file, a.out_dir, a.quiet, a.in, a.method, a.budget);
  if (*c.track) return run_track(a.file, a.out_dir, a.quiet, a.in, a.run);
  if (*c.plot) return run_plot(a.out_dir);
  if (*c.report) return run_report(a.out_dir, a.scenario, a.report_out, a.quiet, a.in, a.mesh_budget);
  if (*c.paper) return run_paper_command(a.out_dir, a.quiet, a.report, a.run.jobs < 0 ? 0 : a.run.jobs);
  if (*c.generate) return run_generate(a.file, a.out_dir, a.formats, a.prefix, a.quiet, a.in);
  if (*c.kinds) return run_kinds(a.sections);
  return kOk;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace refdyn::app;
  CLI::App app{"refdyn: task-based motion planning from computationally generated reference dynamics"};
  app.footer(
      "Exit codes: 0 success; 1 bad command line; 2 invalid input (scenario, model, option): nothing written;\n"
      "            3 internal error; 4 a run stopped early (diverged, singular partition): partial results written;\n"
      "            also 4: optimize found no feasible point, plan --require-feasible planned a motion not feasible.\n"
      "Scenario format: docs/scenario.md (`refdyn kinds` lists constraint kinds, forces, controllers).\n"
      "Examples: examples/*/*.yaml.");
  app.set_version_flag("--version", std::string("refdyn ") + refdyn::version(), "Print the version and exit");
  app.require_subcommand(1);
  Args args;
  Commands commands{};
  add_scenario_commands(app, args, commands);
  add_other_commands(app, args, commands);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e) == 0 ? kOk : kUsage;
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e) == 0 ? kOk : kUsage;
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e) == 0 ? kOk : kUsage;
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::fprintf(stderr, "refdyn: error: %s\n", usage_message(e, argc, argv, kCommandNames).c_str());
    return kUsage;
  }
  try {
    return dispatch(commands, args);
  } catch (const refdyn::Error& e) {
    std::string msg = e.what();
    for (char& ch : msg)
      if (ch == '\n') ch = ' ';
    if (error_output()) std::fprintf(stderr, "refdyn: error: %s\n", msg.c_str());
    return kBadInput;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "refdyn: error: out of memory (hint: reduce the time span, the output rate or the sweep)\n");
    return kBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "refdyn: internal error: %s (please report)\n", e.what());
    return kInternal;
  }
}
