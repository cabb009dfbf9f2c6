// refdyn plot: figures of a results folder, drawn by the matplotlib scripts in scripts/.
// The script runs as a child process with an argument vector (posix_spawn): no shell ever
// sees the folder name, so quotes, $(...), backticks, spaces, newlines or a leading '-' in it
// are just characters of a path.
#include "commands.hpp"

#include "refdyn/common/error.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

extern char** environ;

namespace refdyn::app {

namespace fs = std::filesystem;

namespace {

constexpr const char* kPython = "/usr/bin/python3";

/// Runs args[0] with argument vector `args` (no shell, no PATH lookup) and waits for it.
/// Returns the wait status, or -1 (after printing one line) when it cannot be started.
int spawn_and_wait(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ);
  if (rc != 0) {
    std::fprintf(stderr, "refdyn: error: %s: cannot run it (%s) (hint: bash scripts/install-deps.sh installs python3-matplotlib)\n",
                 argv[0], std::strerror(rc));
    return -1;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) == -1) {
    if (errno != EINTR) throw std::runtime_error(std::string("waitpid: ") + std::strerror(errno));
  }
  return status;
}

}  // namespace

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
    if (!fs::exists(p)) continue;
    // An absolute folder path: a name starting with '-' can never look like an option.
    const int status = spawn_and_wait({kPython, p.string(), fs::absolute(dir).string()});
    if (status == -1) return kInternal;
    if (WIFEXITED(status)) {
      const int code = WEXITSTATUS(status);
      if (code == 0) return kOk;
      if (code == 2) return kBadInput;  // bad input: the script printed one line "refdyn: error: ..."
      std::fprintf(stderr, "refdyn: internal error: %s exited with status %d (please report)\n", p.c_str(), code);
      return kInternal;
    }
    std::fprintf(stderr, "refdyn: internal error: %s killed by signal %d (please report)\n", p.c_str(),
                 WIFSIGNALED(status) ? WTERMSIG(status) : -1);
    return kInternal;
  }
  throw Error(std::string("plotting script ") + script + " not found next to the refdyn executable");
}

}  // namespace refdyn::app
