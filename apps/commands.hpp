#pragma once
#include <string>

namespace refdyn::app {

/// Exit codes of the refdyn command (documented in the README and `refdyn --help`).
enum ExitCode : int {
  kOk = 0,
  kUsage = 1,           ///< bad command line (CLI11 prints the reason)
  kBadInput = 2,        ///< invalid scenario, model or option: nothing was written
  kInternal = 3,        ///< a bug: please report
  kNumerical = 4,       ///< a run stopped early (divergence, singular partition): partial results written
};

int run_check(const std::string& file);
int run_plan(const std::string& file, const std::string& out_dir, bool quiet);
int run_track(const std::string& file, const std::string& out_dir, bool quiet);
int run_plot(const std::string& dir);

}  // namespace refdyn::app
