// refdyn command line. Library errors (refdyn::Error) are caught once here, printed as one
// line, and mapped to the documented exit codes (commands.hpp).
#include "commands.hpp"
#include "paper_study_output.hpp"
#include "refdyn/error.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>

int main(int argc, char** argv) {
  using namespace refdyn::app;
  CLI::App app{"refdyn: task-based motion planning from computationally generated reference dynamics"};
  app.footer(
      "Exit codes: 0 success; 1 bad command line; 2 invalid input (scenario, model, option): nothing written;\n"
      "            3 internal error; 4 a run stopped early (diverged, singular partition): partial results written.\n"
      "Scenario format: docs/scenario.md. Examples: examples/*/*.yaml.");
  app.require_subcommand(1);
  std::string file, out_dir = "results";
  bool quiet = false;

  auto* check = app.add_subcommand("check", "Validate a scenario and print its summary (DOF, constraints, partition, residuals)");
  check->add_option("file", file, "Scenario file (YAML)")->required();

  auto* plan = app.add_subcommand("plan", "Solve the reference dynamics: planned motion (CSV), feasibility report (JSON)");
  plan->add_option("file", file, "Scenario file (YAML)")->required();
  plan->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  plan->add_flag("-q,--quiet", quiet, "Print nothing on success");

  auto* track = app.add_subcommand("track", "Plan, then run the scenario's closed-loop tracking experiments");
  track->add_option("file", file, "Scenario file (YAML)")->required();
  track->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  track->add_flag("-q,--quiet", quiet, "Print nothing on success");

  auto* plot = app.add_subcommand("plot", "Draw the figures (PNG + PDF) of a results folder");
  plot->add_option("dir", out_dir, "Results folder written by plan, track or paper")->required();

  auto* paper = app.add_subcommand("paper", "Run the paper's three-link manipulator study (the main job)");
  paper->add_option("-o,--output", out_dir, "Output folder")->capture_default_str();
  paper->add_flag("-q,--quiet", quiet, "Print nothing on success");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? kOk : kUsage;
  }
  try {
    if (*check) return run_check(file);
    if (*plan) return run_plan(file, out_dir, quiet);
    if (*track) return run_track(file, out_dir, quiet);
    if (*plot) return run_plot(out_dir);
    if (*paper) return run_paper_command(out_dir, quiet);
  } catch (const refdyn::Error& e) {
    std::fprintf(stderr, "refdyn: error: %s\n", e.what());
    return kBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "refdyn: internal error: %s (please report)\n", e.what());
    return kInternal;
  }
  return kOk;
}
