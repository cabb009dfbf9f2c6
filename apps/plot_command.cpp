// refdyn plot: figures of a results folder, drawn by the matplotlib scripts in scripts/.
#include "commands.hpp"

#include "refdyn/error.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace refdyn::app {

namespace fs = std::filesystem;

int run_plot(const std::string& dir) {
  if (!fs::is_directory(dir)) throw Error("results folder '" + dir + "': not found (hint: run refdyn plan/track/paper first)");
  if (!fs::exists(fs::path(dir) / "plan.csv"))
    throw Error("results folder '" + dir + "': no plan.csv in it (hint: point to a folder written by refdyn plan/track/paper)");
  // The plotting scripts live next to the executable's source tree or in share/.
  const fs::path exe = fs::canonical("/proc/self/exe");
  std::vector<fs::path> roots{exe.parent_path().parent_path().parent_path(), exe.parent_path().parent_path() / "share/refdyn"};
  std::ifstream sj(fs::path(dir) / "summary.json");
  std::stringstream ss;
  ss << sj.rdbuf();
  const bool paper = ss.str().find("\"study\": \"paper three-link manipulator\"") != std::string::npos;
  const char* script = paper ? "scripts/plot_study.py" : "scripts/plot_results.py";
  for (const auto& r : roots) {
    const fs::path p = r / script;
    if (fs::exists(p)) {
      const std::string cmd = "/usr/bin/python3 '" + p.string() + "' '" + dir + "'";
      const int rc = std::system(cmd.c_str());
      return rc == 0 ? kOk : kInternal;
    }
  }
  throw Error(std::string("plotting script ") + script + " not found next to the refdyn executable");
}

}  // namespace refdyn::app
