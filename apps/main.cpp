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

}  // namespace

int main(int argc, char** argv) {
  using namespace refdyn::app;
  CLI::App app{"refdyn: task-based motion planning from computationally generated reference dynamics"};
  app.footer(
      "Exit codes: 0 success; 1 bad command line; 2 invalid input (scenario, model, option): nothing written;\n"
      "            3 internal error; 4 a run stopped early (diverged, singular partition): partial results written.\n"
      "Scenario format: docs/scenario.md (`refdyn kinds` lists constraint kinds, forces, controllers).\n"
      "Examples: examples/*/*.yaml.");
  app.set_version_flag("--version", std::string("refdyn ") + refdyn::version(), "Print the version and exit");
  app.require_subcommand(1);
  std::string file, out_dir = "results";
  bool quiet = false, report = false;
  std::string scenario, report_out;
  InputOptions in;

  auto input_options = [&](CLI::App* c) {
    c->add_option("--max-input-size", in.max_input_bytes, "Largest scenario or URDF file read [bytes]")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
  };

  auto* check = app.add_subcommand("check", "Validate a scenario and print its summary (DOF, constraints, partition, residuals)");
  check->add_option("file", file, "Scenario file (YAML)")->required();
  input_options(check);

  auto* plan = app.add_subcommand("plan", "Solve the reference dynamics: planned motion (CSV), feasibility report (JSON)");
  plan->add_option("file", file, "Scenario file (YAML)")->required();
  plan->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  plan->add_flag("-q,--quiet", quiet, "Print nothing on success");
  plan->add_flag("--report", report, "Also write report.html (interactive plots, 3D replay; docs/report.md)");
  input_options(plan);
  RunConfig run;
  auto run_options = [&run](CLI::App* c, const char* what) {
    c->add_option("-j,--jobs", run.jobs,
                  std::string("Threads running ") + what + " (0: every core; default: every core, 1 per rank with --mpi); "
                  "results do not depend on it")
        ->check(CLI::NonNegativeNumber);
    c->add_option("--run-csv", run.run_csv,
                  std::string("Per-run files (track_<name>.csv; for variants: a folder each): all, none, or auto (all up "
                              "to 100); the aggregate (sweep.csv / variants.csv, summary.json) always"))
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "all", "none"}));
    c->add_flag("--mpi", run.mpi,
                "Spread the runs or variants over MPI ranks (mpirun -np N refdyn ... --mpi; DIR on a shared file "
                "system); the files are those of one process (docs/sweeps.md)");
  };
  run_options(plan, "the scenario's variants");

  auto* track = app.add_subcommand("track", "Plan, then run the scenario's closed-loop tracking experiments");
  track->add_option("file", file, "Scenario file (YAML)")->required();
  track->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  track->add_flag("-q,--quiet", quiet, "Print nothing on success");
  track->add_flag("--report", report, "Also write report.html (interactive plots, 3D replay; docs/report.md)");
  run_options(track, "experiments (or variants)");
  input_options(track);

  auto* plot = app.add_subcommand("plot", "Draw the figures (PNG + PDF) of a results folder");
  plot->add_option("dir", out_dir, "Results folder written by plan, track or paper")->required();

  auto* paper = app.add_subcommand("paper", "Run the paper's three-link manipulator study (the main job)");
  paper->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  paper->add_flag("-q,--quiet", quiet, "Print nothing on success");
  paper->add_flag("--report", report, "Also write report.html (interactive plots, 3D replay; docs/report.md)");
  paper->add_option("-j,--jobs", run.jobs, "Threads running the four tracking runs (0 or default: every core)")
      ->check(CLI::NonNegativeNumber);

  auto* rep = app.add_subcommand(
      "report", "Write DIR/report.html: one self-contained HTML file with the summary, interactive plots and a 3D replay");
  rep->add_option("dir", out_dir, "Results folder written by plan, track or paper")->required();
  rep->add_option("--scenario", scenario,
                  "Scenario file of the results (default: the one summary.json names; built in for paper results)");
  rep->add_option("-o,--output", report_out, "Report file (default: DIR/report.html)");
  rep->add_flag("-q,--quiet", quiet, "Print nothing on success");
  input_options(rep);

  std::string formats = "c,latex,json", prefix;
  auto* generate = app.add_subcommand(
      "generate", "Generate the reference dynamics as equations and code: equations.tex, reference_dynamics.c/.h, .json");
  generate->add_option("file", file, "Scenario file (YAML)")->required();
  generate->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  generate->add_option("--format", formats, "Comma-separated outputs: c, latex, json")->capture_default_str();
  generate->add_option("--prefix", prefix, "Prefix of the C identifiers (default: rd_<scenario name>_)");
  generate->add_flag("-q,--quiet", quiet, "Print nothing on success");
  input_options(generate);

  auto* kinds = app.add_subcommand("kinds", "List the constraint kinds, force elements and controllers with their keys");

  const std::vector<std::string> commands{"check", "plan", "track", "plot", "report", "paper", "generate", "kinds"};
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
    std::fprintf(stderr, "refdyn: error: %s\n", usage_message(e, argc, argv, commands).c_str());
    return kUsage;
  }
  try {
    if (*check) return run_check(file, in);
    if (report) require_report_template();
    run.report = report;
    if (*plan) return run_plan(file, out_dir, quiet, in, run);
    if (*track) return run_track(file, out_dir, quiet, in, run);
    if (*plot) return run_plot(out_dir);
    if (*rep) return run_report(out_dir, scenario, report_out, quiet, in);
    if (*paper) return run_paper_command(out_dir, quiet, report, run.jobs < 0 ? 0 : run.jobs);
    if (*generate) return run_generate(file, out_dir, formats, prefix, quiet, in);
    if (*kinds) return run_kinds();
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
  return kOk;
}
