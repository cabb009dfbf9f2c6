#pragma once
#include <string>

namespace refdyn::app {
/// `refdyn paper`: runs the paper's study and writes CSV/JSON results into out_dir (and
/// report.html with `report`).
/// jobs: threads for the four tracking runs (0: every core); the numbers do not depend on it.
int run_paper_command(const std::string& out_dir, bool quiet, bool report = false, int jobs = 0);
}
