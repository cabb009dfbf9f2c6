#pragma once
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"

#include <cstddef>
#include <string>

namespace refdyn::app {

/// Exit codes of the refdyn command (documented in the README and `refdyn --help`).
enum ExitCode : int {
  kOk = 0,
  kUsage = 1,           ///< bad command line
  kBadInput = 2,        ///< invalid scenario, model or option: nothing was written
  kInternal = 3,        ///< a bug: please report
  kNumerical = 4,       ///< a run stopped early (divergence, singular partition): partial results written
};

/// Options shared by the commands that read a scenario.
struct InputOptions {
  std::size_t max_input_bytes = io::kDefaultMaxInputBytes;
};

/// A progress bar on stderr (terminal only, after one second) for runs of the pipeline.
io::ProgressFactory terminal_progress(bool enabled);

/// One line on stderr per run that stopped early (printed even with -q).
void report_stopped(const io::Results& results);

int run_check(const std::string& file, const InputOptions& in);
int run_plan(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in, bool report = false);
int run_track(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in, bool report = false);
int run_plot(const std::string& dir);
int run_kinds();
int run_generate(const std::string& file, const std::string& out_dir, const std::string& formats,
                 const std::string& prefix, bool quiet, const InputOptions& in);

}  // namespace refdyn::app
