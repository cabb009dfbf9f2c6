// `refdyn plot` (apps/plot_command.cpp, scripts/plot_results.py, scripts/plot_study.py):
//  - hostile results-folder names (quotes, $(...), backticks, spaces, newlines, a leading '-',
//    ';', '|', '&', backslashes) give figures or a clean error and never run the embedded
//    command (no PWNED file appears in the scratch area, the test's working directory or the
//    temporary folder);
//  - a corrupted, binary, non-UTF-8, empty or column-less CSV and a broken summary.json give
//    exit status 2, exactly one stderr line "refdyn: error: FILE: ...", and no figure;
//  - the figures get the same file mode as the CSV files (0666 minus the umask).
// The CLI runs as a child process with an argument vector (posix_spawn), never via a shell.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace fs = std::filesystem;

namespace {

const fs::path kSource = REFDYN_SOURCE_DIR;
const fs::path kCli = REFDYN_CLI;
const fs::path kScenario = kSource / "examples/planar_2r_circle/planar_2r_circle.yaml";
const std::vector<std::string> kPlanFigures{"plan_joints", "plan_efforts"};

std::string read_text(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

void write_text(const fs::path& p, const std::string& s) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f << s;
}

/// A fresh temporary folder (absolute path), removed with everything in it at the end.
class Scratch {
 public:
  Scratch() {
    static std::atomic<int> counter{0};
    root_ = fs::temp_directory_path() /
            ("refdyn_plot_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(root_);
    fs::create_directories(root_ / "cwd");
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  const fs::path& root() const { return root_; }
  fs::path cwd() const { return root_ / "cwd"; }

 private:
  fs::path root_;
};

struct Result {
  std::vector<std::string> args;
  int code = -1;  ///< exit code, 128 + signal if killed
  std::string out, err;
};

std::string describe(const Result& r) {
  std::string s = "\n  command: refdyn";
  for (size_t i = 1; i < r.args.size(); ++i) s += " [" + r.args[i] + "]";
  return s + "\n  exit code: " + std::to_string(r.code) + "\n  stderr: [" + r.err + "]\n  stdout: [" +
         r.out.substr(0, 400) + "]";
}

/// Runs the refdyn CLI with `args` (an argument vector: no shell) in `cwd`, stdout and stderr
/// captured in files under `capture`, stdin from /dev/null.
Result run_cli(const std::vector<std::string>& args, const fs::path& cwd, const fs::path& capture) {
  Result r;
  r.args = {kCli.string()};
  r.args.insert(r.args.end(), args.begin(), args.end());
  fs::create_directories(capture);
  const fs::path out = capture / "stdout", err = capture / "stderr";
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addchdir_np(&fa, cwd.c_str());
  std::vector<char*> argv;
  for (auto& a : r.args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    r.err = "posix_spawn failed: " + std::to_string(rc);
    return r;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) == -1 && errno == EINTR) {
  }
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

int count_lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

::testing::AssertionResult one_error_line(const Result& r, const std::string& mentions) {
  if (r.err.empty() || r.err.back() != '\n' || count_lines(r.err) != 1)
    return ::testing::AssertionFailure() << "stderr is not exactly one line (" << count_lines(r.err)
                                         << " newlines)" << describe(r);
  if (r.err.rfind("refdyn: error: ", 0) != 0)
    return ::testing::AssertionFailure() << "stderr does not start with \"refdyn: error: \"" << describe(r);
  if (r.err.find(mentions) == std::string::npos)
    return ::testing::AssertionFailure() << "stderr does not name " << mentions << describe(r);
  return ::testing::AssertionSuccess();
}

/// Every regular file named PWNED* below `dir` (recursively; errors ignored).
std::vector<fs::path> pwned_files(const fs::path& dir) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
       it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (ec) break;
    if (it->path().filename().string().rfind("PWNED", 0) == 0) found.push_back(it->path());
  }
  return found;
}

/// Final figure files (not temporaries) in dir/figures.
std::vector<std::string> figure_files(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir / "figures", ec)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

/// A valid results folder, planned once per test process into `dir` (copied from a cache).
void make_results(const fs::path& dir) {
  static const fs::path cache = [] {
    const fs::path c = fs::temp_directory_path() / ("refdyn_plot_test_results_" + std::to_string(::getpid()));
    fs::remove_all(c);
    const Result r = run_cli({"plan", kScenario.string(), "-o", c.string(), "-q"}, fs::temp_directory_path(),
                             c.string() + ".capture");
    fs::remove_all(c.string() + ".capture");
    if (r.code != 0 || !fs::exists(c / "plan.csv")) {
      ADD_FAILURE() << "refdyn plan failed" << describe(r);
    }
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(fs::temp_directory_path() / ("refdyn_plot_test_results_" + std::to_string(::getpid())), ec);
    });
    return c;
  }();
  fs::create_directories(dir);
  fs::copy(cache, dir, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
}

// ---------------------------------------------------------------------------------------------
// Hostile folder names.

struct Hostile {
  const char* label;
  std::string name;
};

const std::vector<Hostile>& hostile_names() {
  static const std::vector<Hostile> v{
      {"single_quotes", "res'$(touch PWNED_sq)'x"},
      {"double_quotes", "res\"$(touch PWNED_dq)\"x"},
      {"backticks", "res`touch PWNED_bt`x"},
      {"spaces", "res $(touch PWNED_sp) x"},
      {"newline", "res\n$(touch PWNED_nl)\nx"},
      {"leading_dash", "-res;touch PWNED_dash;x"},
      {"leading_double_dash", "--help;touch PWNED_dd"},
      {"pipe_and_ampersand", "res|touch PWNED_pipe&x"},
      {"backslash_dollar", "res\\$(touch PWNED_bs)\\"},
      {"parent_folder_payload", "x'; cd ..; touch PWNED_up; '"},
  };
  return v;
}

class HostileFolderName : public ::testing::TestWithParam<size_t> {};

TEST_P(HostileFolderName, GivesFiguresOrACleanErrorAndNeverRunsTheEmbeddedCommand) {
  const Hostile& h = hostile_names()[GetParam()];
  Scratch s;
  const fs::path dir = s.root() / h.name;
  make_results(dir);
  ASSERT_TRUE(fs::exists(dir / "plan.csv"));

  // Absolute path; then the bare name from its parent folder (after "--" for a leading '-').
  std::vector<std::vector<std::string>> invocations{{"plot", dir.string()}};
  if (h.name[0] == '-')
    invocations.push_back({"plot", "--", h.name});
  else
    invocations.push_back({"plot", h.name});
  for (const auto& args : invocations) {
    fs::remove_all(dir / "figures");
    const bool absolute = args.back() == dir.string();
    const Result r = run_cli(args, absolute ? s.cwd() : s.root(), s.root() / "capture");
    if (absolute) {
      // Through the absolute path the folder is always found: figures, exit 0.
      EXPECT_EQ(r.code, 0) << describe(r);
      EXPECT_EQ(figure_files(dir).size() % 2, 0u) << describe(r);
      EXPECT_GE(figure_files(dir).size(), 2 * kPlanFigures.size()) << describe(r);
    }
    if (r.code == 0) {
      for (const auto& f : kPlanFigures) {
        EXPECT_TRUE(fs::is_regular_file(dir / "figures" / (f + ".png"))) << f << describe(r);
        EXPECT_TRUE(fs::is_regular_file(dir / "figures" / (f + ".pdf"))) << f << describe(r);
      }
    } else {
      EXPECT_TRUE(r.code == 1 || r.code == 2) << describe(r);
      EXPECT_EQ(count_lines(r.err), 1) << describe(r);
    }
    EXPECT_TRUE(pwned_files(s.root()).empty()) << "the embedded command ran" << describe(r);
    EXPECT_TRUE(pwned_files(fs::current_path()).empty()) << "the embedded command ran" << describe(r);
    EXPECT_FALSE(fs::exists(fs::temp_directory_path() / "PWNED_up")) << "the embedded command ran" << describe(r);
  }
}

INSTANTIATE_TEST_SUITE_P(Plot, HostileFolderName, ::testing::Range<size_t>(0, hostile_names().size()),
                         [](const ::testing::TestParamInfo<size_t>& i) { return hostile_names()[i.param].label; });

// ---------------------------------------------------------------------------------------------
// Bad input: exit 2, one line, no figure.

struct BadInput {
  const char* label;
  const char* file;  ///< relative to the results folder
  std::string (*content)(const std::string& original);
  bool paper = false;  ///< route to plot_study.py (summary.json of the paper study)
};

std::string corrupt_row(const std::string& csv) {  // a value in the middle replaced by garbage
  std::string s = csv;
  const size_t line3 = s.find('\n', s.find('\n') + 1) + 1;
  const size_t comma = s.find(',', line3);
  return s.substr(0, comma + 1) + "0.5e+x!" + s.substr(s.find(',', comma + 1));
}
std::string truncated_row(const std::string& csv) {  // a row cut right after a comma
  return csv.substr(0, csv.find(',', csv.size() / 2) + 1) + "\n";
}
std::string binary(const std::string&) {
  std::mt19937 rng(7);
  std::string s(4096, '\0');
  for (auto& c : s) c = static_cast<char>(rng() & 0xff);
  s[10] = '\0';
  return s;
}
std::string latin1(const std::string& csv) {  // not UTF-8, no NUL byte
  return "t,q_\xe9\xe8,q_q2\n" + csv.substr(csv.find('\n') + 1);
}
std::string empty(const std::string&) { return ""; }
std::string header_only(const std::string& csv) { return csv.substr(0, csv.find('\n') + 1); }
std::string missing_column(const std::string& csv) {  // required_<joint> renamed
  std::string s = csv;
  const size_t p = s.find("required_");
  if (p != std::string::npos) s.replace(p, 9, "demanded_");
  return s;
}
std::string bad_json(const std::string&) {
  return "{\"study\": \"paper three-link manipulator\", \"runs\": [1, 2,";
}

const std::vector<BadInput>& bad_inputs() {
  static const std::vector<BadInput> v{
      {"corrupted_number", "plan.csv", corrupt_row},
      {"truncated_row", "plan.csv", truncated_row},
      {"binary_plan_csv", "plan.csv", binary},
      {"non_utf8_plan_csv", "plan.csv", latin1},
      {"empty_plan_csv", "plan.csv", empty},
      {"header_only_plan_csv", "plan.csv", header_only},
      {"missing_column", "plan.csv", missing_column},
      {"paper_binary_plan_csv", "plan.csv", binary, true},
      {"paper_corrupted_plan_csv", "plan.csv", corrupt_row, true},
      {"paper_bad_summary_json", "summary.json", bad_json, true},
  };
  return v;
}

class PlotBadInput : public ::testing::TestWithParam<size_t> {};

TEST_P(PlotBadInput, ExitsTwoWithOneLineAndWritesNoFigure) {
  const BadInput& b = bad_inputs()[GetParam()];
  Scratch s;
  const fs::path dir = s.root() / "results";
  make_results(dir);
  if (b.paper)  // the marker refdyn plot routes on; plot_study.py then reads the inputs
    write_text(dir / "summary.json",
               "{\"study\": \"paper three-link manipulator\", \"ellipse\": {\"a\": 0.35, \"b\": 0.25}, \"runs\": []}\n");
  const fs::path file = dir / b.file;
  write_text(file, b.content(read_text(file)));
  const Result r = run_cli({"plot", dir.string()}, s.cwd(), s.root() / "capture");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, file.string()));
  EXPECT_EQ(r.err.find("Traceback"), std::string::npos) << describe(r);
  EXPECT_TRUE(figure_files(dir).empty()) << "figures or temporaries left behind" << describe(r);
}

INSTANTIATE_TEST_SUITE_P(Plot, PlotBadInput, ::testing::Range<size_t>(0, bad_inputs().size()),
                         [](const ::testing::TestParamInfo<size_t>& i) { return bad_inputs()[i.param].label; });

// ---------------------------------------------------------------------------------------------
// File modes.

TEST(Plot, FiguresGetTheFileModeOfTheCsvFiles) {
  for (const mode_t mask : {mode_t{022}, mode_t{027}}) {
    Scratch s;
    const fs::path dir = s.root() / "results";
    const mode_t old = ::umask(mask);
    const Result plan = run_cli({"plan", kScenario.string(), "-o", dir.string(), "-q"}, s.cwd(), s.root() / "capture");
    const Result r = run_cli({"plot", dir.string()}, s.cwd(), s.root() / "capture");
    ::umask(old);
    ASSERT_EQ(plan.code, 0) << describe(plan);
    ASSERT_EQ(r.code, 0) << describe(r);
    struct stat csv {};
    ASSERT_EQ(::stat((dir / "plan.csv").c_str(), &csv), 0);
    EXPECT_EQ(csv.st_mode & 0777, 0666 & ~mask) << "plan.csv";
    const auto figures = figure_files(dir);
    ASSERT_GE(figures.size(), 2 * kPlanFigures.size());
    for (const auto& f : figures) {
      EXPECT_NE(f[0], '.') << "temporary file left behind: " << f;
      struct stat st {};
      ASSERT_EQ(::stat((dir / "figures" / f).c_str(), &st), 0);
      EXPECT_EQ(st.st_mode & 0777, csv.st_mode & 0777) << f << " (umask " << std::oct << mask << ")";
    }
  }
}

}  // namespace
