// The refdyn command line on malformed and valid scenarios: every malformed scenario in
// tests/data/bad/ (listed with its expected message in tests/data/bad/README.md) is rejected
// with exit code 2, one line "refdyn: error: FILE:LINE: KEY: message" on stderr, and nothing
// written; usage errors give exit code 1, --help exit code 0; the minimal valid scenario
// (tests/data/good/minimal.yaml) is checked and planned.
#include "refdyn/common/json.hpp"
#include "refdyn/io/csv.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path kSource = REFDYN_SOURCE_DIR;
const fs::path kBadDir = kSource / "tests/data/bad";
const fs::path kGood = kSource / "tests/data/good/minimal.yaml";

std::string quote(const fs::path& p) { return "'" + p.string() + "'"; }

std::string read_text(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// A fresh temporary folder, removed with everything in it at the end of the test.
class Scratch {
 public:
  Scratch() {
    static std::atomic<int> counter{0};
    root_ = fs::temp_directory_path() /
            ("refdyn_cli_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(root_);
    fs::create_directories(root_ / "cwd");
    fs::create_directories(root_ / "capture");
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  const fs::path& root() const { return root_; }
  fs::path cwd() const { return root_ / "cwd"; }          ///< the command's working directory
  fs::path capture() const { return root_ / "capture"; }  ///< its stdout and stderr
 private:
  fs::path root_;
};

struct Result {
  std::string command;
  int code = -1;  ///< exit code (a shell reports a signal as 128 + signal)
  std::string out, err;
};

/// Runs `refdyn ARGS` in scratch.cwd() with stdout/stderr redirected to files.
Result run(const Scratch& s, const std::string& args) {
  Result r;
  r.command = "refdyn " + args;
  const std::string cmd = "cd " + quote(s.cwd()) + " && " + quote(REFDYN_CLI) + " " + args + " >" +
                          quote(s.capture() / "stdout") + " 2>" + quote(s.capture() / "stderr") + " </dev/null";
  const int status = std::system(cmd.c_str());
  r.code = status == -1 ? -1 : WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_text(s.capture() / "stdout");
  r.err = read_text(s.capture() / "stderr");
  return r;
}

std::string describe(const Result& r) {
  return "\n  command: " + r.command + "\n  exit code: " + std::to_string(r.code) + "\n  stderr: [" + r.err +
         "]\n  stdout: [" + r.out.substr(0, 400) + "]";
}

/// Folder entries (names), for messages.
std::string listing(const fs::path& dir) {
  std::string s;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) s += " " + e.path().filename().string();
  return s.empty() ? " (empty)" : s;
}

bool empty_dir(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::is_empty(dir, ec);
}

int count_lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

/// The error line is exactly one line "refdyn: error: " + FILE + ...; returns what follows FILE.
::testing::AssertionResult one_error_line(const Result& r, const std::string& file) {
  if (r.err.empty() || r.err.back() != '\n' || count_lines(r.err) != 1)
    return ::testing::AssertionFailure() << "stderr is not exactly one line (" << count_lines(r.err) << " newlines)"
                                         << describe(r);
  const std::string prefix = "refdyn: error: " + file;
  if (r.err.rfind(prefix, 0) != 0)
    return ::testing::AssertionFailure() << "stderr does not start with \"" << prefix << "\"" << describe(r);
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// The corpus of malformed scenarios, read from tests/data/bad/README.md.

struct BadCase {
  std::string file;
  enum class Line { Exact, Optional, None } line_kind = Line::Exact;
  int line_lo = 0, line_hi = 0;
  std::string key;  ///< empty: the message has no key path
  std::vector<std::string> fragments;
};

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

std::vector<BadCase> load_cases() {
  std::vector<BadCase> cases;
  std::ifstream f(kBadDir / "README.md");
  for (std::string line; std::getline(f, line);) {
    if (line.rfind("| ", 0) != 0 || !contains(line, ".yaml |")) continue;
    std::vector<std::string> cols;
    std::stringstream ss(line.substr(1));
    for (std::string c; std::getline(ss, c, '|');) cols.push_back(trim(c));
    if (cols.size() < 4) continue;
    BadCase c;
    c.file = cols[0];
    const std::string& l = cols[1];
    if (l == "-") {
      c.line_kind = BadCase::Line::None;
    } else if (l == "?") {
      c.line_kind = BadCase::Line::Optional;
    } else {
      const auto dash = l.find('-');
      c.line_lo = std::stoi(l.substr(0, dash));
      c.line_hi = dash == std::string::npos ? c.line_lo : std::stoi(l.substr(dash + 1));
    }
    c.key = cols[2] == "-" ? "" : cols[2];
    const std::string& fr = cols[3];
    for (size_t p = fr.find('`'); p != std::string::npos;) {
      const size_t q = fr.find('`', p + 1);
      if (q == std::string::npos) break;
      c.fragments.push_back(fr.substr(p + 1, q - p - 1));
      p = fr.find('`', q + 1);
    }
    cases.push_back(c);
  }
  return cases;
}

const std::vector<BadCase>& bad_cases() {
  static const std::vector<BadCase> cases = load_cases();
  return cases;
}

/// Every problem with one rejected run, as text (empty: all good).
std::vector<std::string> problems_with_rejection(const Result& r, const BadCase& c, const std::string& file) {
  std::vector<std::string> p;
  if (r.code != 2) p.push_back("exit code " + std::to_string(r.code) + ", expected 2");
  if (!r.out.empty()) p.push_back("wrote to stdout");
  if (r.err.empty() || r.err.back() != '\n' || count_lines(r.err) != 1)
    p.push_back("stderr is " + std::to_string(count_lines(r.err)) + " lines, expected exactly one");
  const std::string first = r.err.substr(0, r.err.find('\n'));
  const std::string prefix = "refdyn: error: " + file;
  if (first.rfind(prefix, 0) != 0) {
    p.push_back("does not start with \"" + prefix + "\"");
    return p;
  }
  std::string rest = first.substr(prefix.size());
  int line = -1;
  if (rest.size() > 1 && rest[0] == ':' && std::isdigit(static_cast<unsigned char>(rest[1]))) {
    size_t k = 1;
    while (k < rest.size() && std::isdigit(static_cast<unsigned char>(rest[k]))) ++k;
    line = std::stoi(rest.substr(1, k - 1));
    rest = rest.substr(k);
  }
  switch (c.line_kind) {
    case BadCase::Line::None:
      if (line >= 0) p.push_back("has a line number " + std::to_string(line) + ", expected none");
      break;
    case BadCase::Line::Optional:
      break;
    case BadCase::Line::Exact:
      if (line < 0)
        p.push_back("has no line number after the file name, expected line " + std::to_string(c.line_lo) +
                    (c.line_hi != c.line_lo ? "-" + std::to_string(c.line_hi) : ""));
      else if (line < c.line_lo || line > c.line_hi)
        p.push_back("names line " + std::to_string(line) + ", expected line " + std::to_string(c.line_lo) +
                    (c.line_hi != c.line_lo ? "-" + std::to_string(c.line_hi) : ""));
      break;
  }
  if (rest.rfind(": ", 0) != 0) {
    p.push_back("no \": \" after the file name and line");
    return p;
  }
  rest = rest.substr(2);
  if (!c.key.empty()) {
    if (rest.rfind(c.key + ": ", 0) != 0) {
      p.push_back("key path is not \"" + c.key + "\" (message after the line: \"" + rest.substr(0, 60) + "\")");
    } else {
      rest = rest.substr(c.key.size() + 2);
    }
  }
  for (const auto& f : c.fragments)
    if (!contains(rest, f)) p.push_back("message lacks \"" + f + "\"");
  return p;
}

void PrintTo(const BadCase& c, std::ostream* os) { *os << c.file; }

class BadScenario : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadScenario, RejectedWithOneLineAndNothingWritten) {
  const BadCase& c = GetParam();
  const std::string file = (kBadDir / c.file).string();
  ASSERT_TRUE(fs::exists(file)) << file;
  Scratch s;
  const fs::path out_empty = s.root() / "out_empty", out_new = s.root() / "out_new" / "nested",
                 track_new = s.root() / "track_new";
  fs::create_directories(out_empty);
  std::vector<std::string> commands{
      "check " + quote(file),
      "plan " + quote(file) + " -o " + quote(out_empty),
      "plan " + quote(file) + " -o " + quote(out_new),
      "track " + quote(file) + " -o " + quote(track_new) + " --report",
  };
  if (contains(read_text(file), "\noptimize:"))  // refdyn optimize rejects it the same way
    commands.push_back("optimize " + quote(file) + " -o " + quote(out_new));
  // The same problem in several commands is reported once, with the first command's output.
  std::vector<std::pair<std::string, Result>> found;
  std::vector<std::vector<std::string>> in_commands;
  for (const auto& cmd : commands) {
    const Result r = run(s, cmd);
    for (const auto& p : problems_with_rejection(r, c, file)) {
      auto it = std::find_if(found.begin(), found.end(), [&](const auto& f) { return f.first == p; });
      if (it == found.end()) {
        found.emplace_back(p, r);
        in_commands.push_back({});
        it = found.end() - 1;
      }
      in_commands[it - found.begin()].push_back(cmd.substr(0, cmd.find(' ')));
    }
  }
  for (size_t i = 0; i < found.size(); ++i) {
    std::string which;
    for (const auto& w : in_commands[i]) which += (which.empty() ? "" : ", ") + w;
    ADD_FAILURE() << c.file << ": " << found[i].first << " [" << which << "]" << describe(found[i].second);
  }
  EXPECT_TRUE(empty_dir(out_empty)) << c.file << ": the existing output folder is no longer empty:" << listing(out_empty);
  EXPECT_FALSE(fs::exists(s.root() / "out_new")) << c.file << ": a not-yet-existing output folder was created";
  EXPECT_FALSE(fs::exists(track_new)) << c.file << ": track created its output folder";
  EXPECT_TRUE(empty_dir(s.cwd())) << c.file << ": something was written in the working directory:" << listing(s.cwd());
}

std::string case_name(const ::testing::TestParamInfo<BadCase>& info) {
  std::string n = info.param.file.substr(0, info.param.file.rfind('.'));
  for (char& ch : n)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return n;
}

INSTANTIATE_TEST_SUITE_P(Corpus, BadScenario, ::testing::ValuesIn(bad_cases()), case_name);

TEST(BadCorpus, EveryFileIsListedAndEveryListedFileExists) {
  const auto& cases = bad_cases();
  EXPECT_GE(cases.size(), 35u) << "tests/data/bad/README.md should list at least 35 malformed scenarios";
  std::set<std::string> listed;
  for (const auto& c : cases) {
    EXPECT_TRUE(listed.insert(c.file).second) << c.file << " is listed twice";
    EXPECT_TRUE(fs::exists(kBadDir / c.file)) << c.file << " is listed but does not exist";
    EXPECT_FALSE(c.fragments.empty()) << c.file << " has no expected message fragment";
  }
  for (const auto& e : fs::directory_iterator(kBadDir)) {
    if (e.path().extension() == ".yaml") {
      EXPECT_TRUE(listed.count(e.path().filename().string())) << e.path().filename() << " is not listed in README.md";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The valid minimal scenario.

TEST(GoodScenario, CheckPrintsDofAndResiduals) {
  Scratch s;
  const Result r = run(s, "check " + quote(kGood));
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_TRUE(contains(r.out, "valid")) << describe(r);
  EXPECT_TRUE(contains(r.out, "2 degrees of freedom")) << describe(r);
  EXPECT_TRUE(contains(r.out, "constraints: 1 (1 rows)")) << describe(r);
  EXPECT_TRUE(contains(r.out, "partition: independent [j2], dependent [j1]")) << describe(r);
  EXPECT_TRUE(contains(r.out, "initial residuals")) << describe(r);
  EXPECT_TRUE(contains(r.out, "tip_x") && contains(r.out, "|Phi| = ") && contains(r.out, "|dPhi/dt| = ")) << describe(r);
  EXPECT_EQ(r.err, "");
  EXPECT_TRUE(empty_dir(s.cwd())) << "check wrote something:" << listing(s.cwd());
}

// `refdyn check --json`: the report's fields (Fields<io::CheckReport>), the keys Python's
// refdyn.check has, for a scenario with a partition and an RK4 integrator and for a jerk problem
// with an initial acceleration consistent with its rows.
TEST(GoodScenario, CheckJsonIsTheReportsFields) {
  Scratch s;
  Result r = run(s, "check --json " + quote(kGood));
  ASSERT_EQ(r.code, 0) << describe(r);
  refdyn::JsonValue j = refdyn::parse_json(r.out, "check --json");
  EXPECT_EQ(j["scenario"], "minimal_arm");
  EXPECT_EQ(j["valid"], true);
  EXPECT_EQ(j["joints"], refdyn::JsonValue::array({"j1", "j2"}));
  EXPECT_EQ(j["rows"]["total"], 1);
  EXPECT_EQ(j["constraints"][0]["name"], "tip_x");
  EXPECT_EQ(j["partition"]["independent"], refdyn::JsonValue::array({"j2"}));
  EXPECT_GE(j["partition"]["condition"].get<double>(), 1.0);  // ‖A‖₁ ‖K_dc⁻¹‖₁ ≥ 1
  EXPECT_TRUE(j["initial_acceleration"].is_null());
  EXPECT_TRUE(j["residuals"]["tip_x"].contains("|Phi|")) << r.out;
  EXPECT_EQ(j["integrator"]["method"], "rk4");
  EXPECT_TRUE(j["integrator"].contains("step"));
  EXPECT_FALSE(j["integrator"].contains("rtol")) << "an RK4 integrator has no tolerances";
  EXPECT_FALSE(j.contains("text")) << "the text is the command's other output";
  EXPECT_EQ(r.err, "");
  EXPECT_TRUE(empty_dir(s.cwd())) << listing(s.cwd());

  r = run(s, "check --json " + quote(kSource / "examples/mixed_orders/mixed_orders.yaml"));
  ASSERT_EQ(r.code, 0) << describe(r);
  j = refdyn::parse_json(r.out, "check --json");
  EXPECT_EQ(j["initial_acceleration"]["source"], "consistent_with");
  EXPECT_EQ(j["initial_acceleration"]["consistent_with"], refdyn::JsonValue::array({"wrist"}));
  EXPECT_EQ(j["initial_acceleration"]["values"].size(), 3u);
  EXPECT_EQ(j["rows"]["jerk"], 1);
}

void expect_plan_written(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    names.insert(n);
    EXPECT_FALSE(contains(n, ".tmp")) << "leftover temporary file " << e.path();
  }
  EXPECT_EQ(names, (std::set<std::string>{"plan.csv", "feasibility.json", "summary.json"})) << listing(dir);
  const std::string csv = read_text(dir / "plan.csv");
  EXPECT_EQ(csv.rfind("t,q_j1,q_j2,qd_j1,qd_j2,", 0), 0u) << csv.substr(0, 200);
  EXPECT_GT(count_lines(csv), 100);  // t = 0 .. 0.5 s with step 1e-3
  EXPECT_TRUE(contains(csv, "phi_tip_x")) << csv.substr(0, 400);
  const std::string summary = read_text(dir / "summary.json");
  EXPECT_TRUE(contains(summary, "\"scenario\": \"minimal_arm\"")) << summary;
  EXPECT_TRUE(contains(summary, "\"status\": \"success\"")) << summary;
  EXPECT_FALSE(read_text(dir / "feasibility.json").empty());
}

TEST(GoodScenario, PlanWritesResultsIntoANewFolder) {
  Scratch s;
  const fs::path out = s.root() / "new" / "results";
  const Result r = run(s, "plan " + quote(kGood) + " -o " + quote(out));
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_EQ(r.err, "");
  EXPECT_TRUE(contains(r.out, "2 DOF")) << describe(r);
  EXPECT_TRUE(contains(r.out, out.string())) << describe(r);
  expect_plan_written(out);
  EXPECT_TRUE(empty_dir(s.cwd())) << listing(s.cwd());
}

TEST(GoodScenario, PlanWritesResultsIntoAnExistingFolderQuietly) {
  Scratch s;
  const fs::path out = s.root() / "out";
  fs::create_directories(out);
  const Result r = run(s, "plan -q " + quote(kGood) + " --output " + quote(out));
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_EQ(r.out, "") << "-q must print nothing on success";
  EXPECT_EQ(r.err, "");
  expect_plan_written(out);
  // A second run over existing results replaces them.
  const Result again = run(s, "plan -q " + quote(kGood) + " -o " + quote(out));
  ASSERT_EQ(again.code, 0) << describe(again);
  expect_plan_written(out);
}

// ---------------------------------------------------------------------------------------------
// Output folders that cannot be written, missing inputs.

/// Columns of a CSV file written by refdyn, by header name (refdyn::io::read_csv_numbers).
std::map<std::string, std::vector<double>> read_columns(const fs::path& file) {
  const refdyn::io::CsvTable t = refdyn::io::read_csv_numbers(file.string());
  std::map<std::string, std::vector<double>> cols;
  for (const auto& row : t.rows)
    for (size_t c = 0; c < t.header.size(); ++c) cols[t.header[c]].push_back(row[c]);
  return cols;
}

// Controller gains per experiment, swept like any parameter. With no plant forces the plant is
// the controller's own model, so each joint error follows the computed-torque closed form
// e(t) = (e0 + (ė0 + δ e0) t) e^(−δt) with that experiment's δ.
TEST(GoodScenario, TrackSweepsControllerGainsPerExperiment) {
  Scratch s;
  const fs::path yaml = s.root() / "sweep_gains.yaml", out = s.root() / "out";
  {
    std::ofstream f(yaml);
    f << read_text(kGood) << R"(
controller: {type: computed_torque_pd, delta: {j1: 10, j2: 10}}
experiments:
  - name: d{d}
    sweep: {d: [5, 20]}
    initial: {q: {j2: 80*deg}, qd: {j1: 0.3}}
    controller: {type: computed_torque_pd, delta: {j1: d, j2: 2*d}}
  - name: top
    initial: {q: {j2: 80*deg}, qd: {j1: 0.3}}
)";
  }
  const Result r = run(s, "track " + quote(yaml) + " -o " + quote(out));
  ASSERT_EQ(r.code, 0) << describe(r);
  const auto plan = read_columns(out / "plan.csv");
  for (const auto& [name, d1] : std::vector<std::pair<std::string, double>>{{"d5", 5}, {"d20", 20}, {"top", 10}}) {
    ASSERT_TRUE(fs::is_regular_file(out / ("track_" + name + ".csv"))) << listing(out);
    const auto tr = read_columns(out / ("track_" + name + ".csv"));
    const double d2 = name == "top" ? 10 : 2 * d1;
    double worst = 0, biggest = 0;
    for (const auto& [j, delta] : std::vector<std::pair<std::string, double>>{{"j1", d1}, {"j2", d2}}) {
      const std::vector<double>& t = tr.at("t");
      const std::vector<double>& e = tr.at("e_" + j);
      ASSERT_EQ(plan.at("t").size(), t.size());
      const double e0 = e[0], ed0 = tr.at("qd_" + j)[0] - plan.at("qd_" + j)[0];
      for (size_t k = 0; k < t.size(); ++k) {
        worst = std::max(worst, std::abs(e[k] - (e0 + (ed0 + delta * e0) * t[k]) * std::exp(-delta * t[k])));
        biggest = std::max(biggest, std::abs(e[k]));
      }
    }
    EXPECT_GT(biggest, 0.1) << name;  // the start is really disturbed
    EXPECT_LT(worst, 1e-6) << name << ": error differs from the closed form with this experiment's gains";
  }
}

TEST(OutputFolder, UnderARegularFileIsRejectedAndNothingIsWritten) {
  Scratch s;
  const fs::path area = s.root() / "area", blocker = area / "file.txt", out = blocker / "sub";
  fs::create_directories(area);
  std::ofstream(blocker) << "keep me\n";
  const Result r = run(s, "plan " + quote(kGood) + " -o " + quote(out));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, ""));
  EXPECT_TRUE(contains(r.err, "'" + out.string() + "'")) << "the message must name the folder" << describe(r);
  EXPECT_EQ(r.out, "") << describe(r);
  EXPECT_EQ(read_text(blocker), "keep me\n");
  EXPECT_TRUE(fs::is_regular_file(blocker));
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(area)) names.insert(e.path().filename().string());
  EXPECT_EQ(names, std::set<std::string>{"file.txt"}) << "half-written output:" << listing(area);
  EXPECT_TRUE(empty_dir(s.cwd())) << listing(s.cwd());
}

TEST(OutputFolder, ThatIsARegularFileIsRejectedAndLeftAlone) {
  Scratch s;
  const fs::path area = s.root() / "area", out = area / "file.txt";
  fs::create_directories(area);
  std::ofstream(out) << "keep me\n";
  const Result r = run(s, "plan " + quote(kGood) + " -o " + quote(out));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, ""));
  EXPECT_TRUE(contains(r.err, "'" + out.string() + "'")) << "the message must name the folder" << describe(r);
  EXPECT_EQ(read_text(out), "keep me\n");
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(area)) names.insert(e.path().filename().string());
  EXPECT_EQ(names, std::set<std::string>{"file.txt"}) << listing(area);
}

TEST(MissingInput, ScenarioFileThatDoesNotExist) {
  Scratch s;
  const fs::path missing = s.root() / "no_such_scenario.yaml", out = s.root() / "out";
  for (const std::string& cmd : {"check " + quote(missing), "plan " + quote(missing) + " -o " + quote(out)}) {
    const Result r = run(s, cmd);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_TRUE(one_error_line(r, ""));
    EXPECT_TRUE(contains(r.err, missing.string())) << describe(r);
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(empty_dir(s.cwd())) << listing(s.cwd());
}

TEST(MissingInput, PlotOnAMissingFolder) {
  Scratch s;
  const fs::path dir = s.root() / "no_results_here";
  const Result r = run(s, "plot " + quote(dir));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, ""));
  EXPECT_TRUE(contains(r.err, dir.string())) << describe(r);
  EXPECT_FALSE(fs::exists(dir));
}

TEST(MissingInput, PlotOnAFolderWithoutResults) {
  Scratch s;
  const fs::path dir = s.root() / "empty_results";
  fs::create_directories(dir);
  const Result r = run(s, "plot " + quote(dir));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, ""));
  EXPECT_TRUE(contains(r.err, dir.string()) && contains(r.err, "plan.csv")) << describe(r);
  EXPECT_TRUE(empty_dir(dir)) << listing(dir);
}

// ---------------------------------------------------------------------------------------------
// Command line.

TEST(CommandLine, UsageErrorsExitWithOneAndWriteNothing) {
  Scratch s;
  const std::string good = quote(kGood);
  const std::vector<std::string> usage_errors{
      "", "frobnicate", "check", "plan", "track", "plot", "plan " + good + " -o", "check " + good + " --bogus",
      "plan " + good + " --bogus", "check " + good + " " + good, "paper --bogus", "report",
      "report a b", "report --bogus"};
  for (const auto& args : usage_errors) {
    const Result r = run(s, args);
    EXPECT_EQ(r.code, 1) << describe(r);
    EXPECT_FALSE(r.err.empty()) << "a usage error must say what is wrong" << describe(r);
    EXPECT_TRUE(empty_dir(s.cwd())) << "'" << args << "' wrote:" << listing(s.cwd());
  }
}

TEST(CommandLine, HelpForEachSubcommand) {
  Scratch s;
  struct H {
    std::string args;
    std::vector<std::string> mentions;
  };
  const std::vector<H> helps{
      {"--help", {"check", "plan", "track", "plot", "report", "paper", "Exit codes"}},
      {"-h", {"check", "plan", "track", "plot", "paper"}},
      {"check --help", {"file", "Scenario file"}},
      {"plan --help", {"file", "-o,--output", "-q,--quiet", "--report"}},
      {"track --help", {"file", "-o,--output", "-q,--quiet", "--report"}},
      {"plot --help", {"dir", "Results folder"}},
      {"report --help", {"dir", "--scenario", "-o,--output"}},
      {"paper --help", {"-o,--output", "-q,--quiet", "--report"}},
  };
  for (const auto& h : helps) {
    const Result r = run(s, h.args);
    EXPECT_EQ(r.code, 0) << describe(r);
    for (const auto& m : h.mentions)
      EXPECT_TRUE(contains(r.out + r.err, m)) << "'refdyn " << h.args << "' does not mention " << m << describe(r);
  }
  EXPECT_TRUE(empty_dir(s.cwd())) << "--help wrote:" << listing(s.cwd());
}

// refdyn --version prints the project's version (project(VERSION) in CMakeLists.txt); summary.json
// records the same as "refdyn_version"; the Python package and CHANGELOG.md name it too.
TEST(CommandLine, VersionIsTheProjectsAndSummaryJsonRecordsIt) {
  Scratch s;
  std::smatch m;
  const std::string cmake = read_text(kSource / "CMakeLists.txt");
  ASSERT_TRUE(std::regex_search(cmake, m, std::regex(R"(project\(refdyn VERSION ([0-9]+\.[0-9]+\.[0-9]+))")));
  const std::string v = m[1];
  const Result r = run(s, "--version");
  EXPECT_EQ(r.code, 0) << describe(r);
  EXPECT_EQ(r.out, "refdyn " + v + "\n") << describe(r);
  EXPECT_EQ(r.err, "");
  EXPECT_TRUE(empty_dir(s.cwd())) << "--version wrote:" << listing(s.cwd());
  const Result p = run(s, "plan " + quote(kGood) + " -o out -q");
  ASSERT_EQ(p.code, 0) << describe(p);
  const std::string summary = read_text(s.cwd() / "out" / "summary.json");
  EXPECT_EQ(summary.rfind("{\n  \"refdyn_version\": \"" + v + "\",\n", 0), 0u) << summary.substr(0, 200);
  EXPECT_TRUE(contains(read_text(kSource / "python/pyproject.toml"), "version = \"" + v + "\""));
  EXPECT_TRUE(contains(read_text(kSource / "python/refdyn/__init__.py"), "__version__ = \"" + v + "\""));
  EXPECT_TRUE(contains(read_text(kSource / "CHANGELOG.md"), "\n## " + v + "\n")) << "CHANGELOG.md has no section " << v;
}

// ---------------------------------------------------------------------------------------------
// Hostile input and outcomes (the hostile-input issue).

/// A copy of the minimal scenario with `from` replaced by `to` (and `extra` appended).
fs::path variant(const Scratch& s, const std::string& name, const std::string& from, const std::string& to,
                 const std::string& extra = "") {
  std::string text = read_text(kGood);
  if (!from.empty()) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  }
  const fs::path p = s.root() / name;
  std::ofstream(p) << text << extra;
  return p;
}

TEST(Outcomes, StoppedRunReportsOneLineEvenWhenQuietAndIsNeverFeasible) {
  Scratch s;
  // The tip is driven out of the arm's reach: the plan diverges near t = 0.8 s.
  const fs::path f = variant(s, "diverge.yaml", "x(E) - (L1 + 0.1*(1 - cos(2*pi*t))/2)", "x(E) - (L1 + 0.5*t)",
                             "");
  std::string text = read_text(f);
  text.replace(text.find("t1: 0.5"), 7, "t1: 1");
  text.replace(text.find("  qd: {j1: 0, j2: 0}"), 20, "  qd: {j1: 0, j2: 0}\n  consistency: project");
  std::ofstream(f) << text;
  const fs::path out = s.root() / "out";
  const Result r = run(s, "plan " + quote(f) + " -q -o " + quote(out));
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_EQ(r.out, "") << describe(r);
  EXPECT_TRUE(one_error_line(r, "the plan stopped early"));
  const std::string feas = read_text(out / "feasibility.json");
  EXPECT_TRUE(contains(feas, "\"feasible\": false")) << feas.substr(0, 200);
  EXPECT_TRUE(contains(feas, "incomplete_reason")) << feas.substr(0, 200);
}

TEST(Outcomes, RejectedInputLeavesAnExistingResultsFolderByteForByteUnchanged) {
  Scratch s;
  const fs::path out = s.root() / "results";
  ASSERT_EQ(run(s, "plan " + quote(kGood) + " -q -o " + quote(out)).code, 0);
  std::map<std::string, std::string> before;
  for (const auto& e : fs::directory_iterator(out)) before[e.path().filename().string()] = read_text(e.path());
  // track without experiments, and a scenario with an error found only when building it
  const fs::path nan = variant(s, "nan.yaml", "expression: x(E)", "expression: sqrt(x(E) - 2) + x(E)");
  for (const std::string& args : {"track " + quote(kGood), "track " + quote(nan), "plan " + quote(nan)}) {
    const Result r = run(s, args + " -o " + quote(out));
    EXPECT_EQ(r.code, 2) << describe(r);
    std::map<std::string, std::string> after;
    for (const auto& e : fs::directory_iterator(out)) after[e.path().filename().string()] = read_text(e.path());
    EXPECT_TRUE(after == before) << args << ": the results folder changed:" << listing(out);
  }
}

// mixed_orders: expression rows of several terms, whose tapes once summed in GiNaC's operand
// order, which is seeded with addresses and changes between processes (the last bits of plan.csv
// did; the compiler now takes operands in a structural order, src/expression/compiler.cpp).
TEST(Outcomes, ResultsAreBitIdenticalAcrossProcesses) {
  Scratch s;
  const std::vector<std::string> files{"examples/unicycle/unicycle.yaml", "examples/four_bar/four_bar.yaml",
                                       "examples/paper/paper.yaml", "examples/mixed_orders/mixed_orders.yaml"};
  for (const auto& rel : files) {
    const std::string cmd = rel.find("paper") != std::string::npos ? "track " : "plan ";
    const fs::path a = s.root() / "a", b = s.root() / "b";
    fs::remove_all(a);
    fs::remove_all(b);
    ASSERT_EQ(run(s, cmd + quote(kSource / rel) + " -q -o " + quote(a)).code, 0) << rel;
    ASSERT_EQ(run(s, cmd + quote(kSource / rel) + " -q -o " + quote(b)).code, 0) << rel;
    int compared = 0;
    for (const auto& e : fs::directory_iterator(a)) {
      const std::string name = e.path().filename().string();
      if (name == "summary.json") continue;  // holds wall times
      EXPECT_EQ(read_text(e.path()), read_text(b / name)) << rel << ": " << name << " differs between two runs";
      ++compared;
    }
    EXPECT_GE(compared, 2) << rel;
  }
  // The texts of differentiated rows (`differentiate: true`) are printed in a fixed order too
  // (source_text, src/expression/source_text.cpp): GiNaC's printout changed between runs.
  const std::string check = "check " + quote(kSource / "examples/mixed_orders/mixed_orders.yaml");
  const Result first = run(s, check), second = run(s, check);
  ASSERT_EQ(first.code, 0) << describe(first);
  EXPECT_NE(first.out.find("wrist: programmed, jerk-level"), std::string::npos) << describe(first);
  EXPECT_EQ(first.out, second.out);
}

// The generator writes a time law into the rows as one expression of t: a law of 128 knot
// speeds (the example) makes them too long, and the message says so and what to do instead of
// the expression engine's generic "split it" (which the user cannot do).
TEST(Generate, ATimeLawTooLongForTheGeneratorIsNamedWithWhatToDo) {
  Scratch s;
  const fs::path out = s.root() / "gen";
  const Result r = run(s, "generate " + quote(kSource / "examples/planar_2r_circle/retime_speeds.yaml") + " -o " +
                              quote(out));
  EXPECT_EQ(r.code, 2) << describe(r);
  for (const char* frag : {"constraint 'ex'", "time law of 128 parts", "669433 characters", "limit of 65536",
                           "without its time_law"})
    EXPECT_NE(r.err.find(frag), std::string::npos) << frag << describe(r);
  EXPECT_EQ(r.err.find("split it"), std::string::npos) << describe(r);
  EXPECT_EQ(count_lines(r.err), 1) << describe(r);
  EXPECT_FALSE(fs::exists(out)) << "nothing is written";
}

TEST(CommandLine, UsageErrorsAreOneLineWithDidYouMean) {
  Scratch s;
  Result r = run(s, "plna " + quote(kGood));
  EXPECT_EQ(r.code, 1) << describe(r);
  EXPECT_TRUE(one_error_line(r, "unknown command 'plna'"));
  EXPECT_TRUE(contains(r.err, "did you mean 'plan'")) << describe(r);
  for (const std::string& args : std::vector<std::string>{"", "check", "plan " + quote(kGood) + " --bogus"}) {
    r = run(s, args);
    EXPECT_EQ(r.code, 1) << describe(r);
    EXPECT_TRUE(one_error_line(r, "")) << args;
  }
}

TEST(CommandLine, KindsListsEveryRegisteredKind) {
  Scratch s;
  const Result r = run(s, "kinds");
  EXPECT_EQ(r.code, 0) << describe(r);
  for (const char* k : {"point_on_ellipse", "distance", "knife_edge", "flexible_drive", "lugre", "computed_torque_pd",
                        "pid_gravity"})
    EXPECT_TRUE(contains(r.out, k)) << k;
}

TEST(Limits, InputFilesAreBoundedAndDevicesRefused) {
  Scratch s;
  Result r = run(s, "check /dev/zero");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, "scenario file '/dev/zero'"));
  EXPECT_TRUE(contains(r.err, "not a regular file")) << describe(r);
  r = run(s, "check " + quote(kGood) + " --max-input-size 100");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(contains(r.err, "limit of 100 bytes")) << describe(r);
}

// ---------------------------------------------------------------------------------------------
// Trust in results (issue 24): size-0 and size-1 scenarios, a plan that misses its task, tracking
// on a plan that stopped early, and the printed condition number.

const fs::path kGoodDir = kSource / "tests/data/good";
const fs::path kStoppedDir = kSource / "tests/data/stopped";

/// The cells of one CSV line (refdyn::io::parse_csv: RFC 4180 quotes).
std::vector<std::string> csv_cells(const std::string& line) { return refdyn::io::parse_csv(line, "line").header; }

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

size_t count_of(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + part.size())) ++n;
  return n;
}

/// The largest |value| of the columns whose header starts with `prefix` (every column: "").
double max_abs_column(const std::string& csv, const std::string& prefix) {
  const auto ls = lines_of(csv);
  if (ls.empty()) return std::nan("");
  const auto head = csv_cells(ls[0]);
  double m = 0;
  for (size_t k = 1; k < ls.size(); ++k) {
    const auto cells = csv_cells(ls[k]);
    for (size_t c = 0; c < head.size() && c < cells.size(); ++c)
      if (head[c].rfind(prefix, 0) == 0) {
        const double v = std::strtod(cells[c].c_str(), nullptr);
        if (!(std::abs(v) <= m)) m = std::abs(v);  // NaN propagates
      }
  }
  return m;
}

TEST(Trust, OneDofModelsAreCheckedPlannedAndTracked) {
  Scratch s;
  const fs::path one = kGoodDir / "one_dof.yaml", free = kGoodDir / "free_one_dof.yaml";
  Result r = run(s, "check " + quote(one));
  EXPECT_EQ(r.code, 0) << describe(r);
  EXPECT_TRUE(contains(r.out, "valid")) << describe(r);
  EXPECT_TRUE(contains(r.out, "independent []")) << describe(r);
  r = run(s, "track " + quote(one) + " -q -o " + quote(s.root() / "one") + " --report");
  EXPECT_EQ(r.code, 0) << describe(r);
  const auto sweep = lines_of(read_text(s.root() / "one" / "sweep.csv"));
  ASSERT_EQ(sweep.size(), 3u);
  for (size_t k = 1; k < sweep.size(); ++k) EXPECT_EQ(csv_cells(sweep[k]).at(2), "success") << sweep[k];
  EXPECT_TRUE(fs::exists(s.root() / "one" / "report.html"));
  // No constraint, no recorded point, an empty experiments list.
  r = run(s, "check " + quote(free));
  EXPECT_EQ(r.code, 0) << describe(r);
  r = run(s, "plan " + quote(free) + " -q -o " + quote(s.root() / "free") + " --report");
  EXPECT_EQ(r.code, 0) << describe(r);
  const std::string plan = read_text(s.root() / "free" / "plan.csv");
  EXPECT_FALSE(contains(plan.substr(0, plan.find('\n')), "phi_")) << plan.substr(0, 200);
  EXPECT_EQ(lines_of(plan).size(), 302u) << "a header and 301 samples";
  EXPECT_TRUE(fs::exists(s.root() / "free" / "report.html"));
  r = run(s, "track " + quote(free) + " -o " + quote(s.root() / "free_track"));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, free.string() + ": experiments: an empty list")) << describe(r);
  EXPECT_FALSE(fs::exists(s.root() / "free_track"));
  // No constraint, but experiments: the plan is the free fall, tracked exactly.
  std::string text = read_text(free);
  text.replace(text.find("experiments: []"), 15,
               "controller: {type: computed_torque_pd, delta: [10]}\nexperiments: [{name: a}, {}]");
  const fs::path tracked = s.root() / "free_track.yaml";
  std::ofstream(tracked) << text;
  r = run(s, "track " + quote(tracked) + " -q -o " + quote(s.root() / "free_track") + " --report");
  EXPECT_EQ(r.code, 0) << describe(r);
  const auto runs = lines_of(read_text(s.root() / "free_track" / "sweep.csv"));
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_EQ(csv_cells(runs[1]).at(1), "a");
  EXPECT_EQ(csv_cells(runs[2]).at(2), "success") << runs[2];
}

TEST(Trust, ZeroDofModelIsOneLocatedError) {
  Scratch s;
  const fs::path f = kBadDir / "model_zero_dof.yaml";
  for (const std::string cmd : {"check ", "plan ", "track "}) {
    const Result r = run(s, cmd + quote(f) + (cmd == "check " ? "" : " -o " + quote(s.root() / "out")));
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_TRUE(one_error_line(r, f.string() + ":")) << describe(r);
    EXPECT_TRUE(contains(r.err, "the model has no moving joint: nothing to plan")) << describe(r);
  }
}

TEST(Trust, PlanThatMissesItsTaskStopsWithItsReasonAndTime) {
  Scratch s;
  // Two RK4 steps of 0.25 s over the 0.5 s motion: without the check the plan "succeeds" with
  // its constraint violated by 0.67; the default tolerance (1e-3) stops it after t0.
  const fs::path f = variant(s, "coarse.yaml", "step: 1e-3", "step: 0.25");
  const fs::path out = s.root() / "out";
  Result r = run(s, "plan " + quote(f) + " -q -o " + quote(out) + " --report");
  EXPECT_EQ(r.code, 4) << describe(r);
  // The step is also outside RK4's stability region for the Baumgarte-stabilized rows (α = 100,
  // β = 50: eigenvalues near −100 to −190 1/s): that comes first, then what the run ended with.
  EXPECT_TRUE(one_error_line(r, "the plan stopped early: the integration is unstable at step h = 0.25 s (from t = "))
      << describe(r);
  EXPECT_TRUE(contains(r.err, "use a step below 0.01")) << describe(r);
  EXPECT_FALSE(contains(r.err, "stiff")) << describe(r);  // a step too long, not a stiff problem
  EXPECT_TRUE(contains(r.err, "The run ended with: at t = 0.25 s the constraint residual")) << describe(r);
  EXPECT_TRUE(contains(r.err, "exceeds integrator.residual_tolerance = 0.001")) << describe(r);
  const std::string summary = read_text(out / "summary.json");
  EXPECT_TRUE(contains(summary, "\"status\": \"residual above tolerance\"")) << summary.substr(0, 600);
  EXPECT_TRUE(contains(summary, "\"residual_tolerance\": 0.001")) << summary.substr(0, 600);
  EXPECT_TRUE(contains(summary, "\"t_end\": 0,")) << summary.substr(0, 600);
  EXPECT_TRUE(contains(read_text(out / "feasibility.json"), "\"feasible\": false"));
  EXPECT_EQ(lines_of(read_text(out / "plan.csv")).size(), 2u) << "the header and t0: the only trustworthy sample";
  EXPECT_TRUE(contains(read_text(out / "report.html"), "residual above tolerance"));
  const fs::path off = variant(s, "coarse_off.yaml", "step: 1e-3", "step: 0.25, residual_tolerance: none");
  r = run(s, "plan " + quote(off) + " -q -o " + quote(s.root() / "off"));
  EXPECT_EQ(r.code, 0) << describe(r);
  EXPECT_GT(max_abs_column(read_text(s.root() / "off" / "plan.csv"), "phi_"), 0.5);
  EXPECT_TRUE(contains(read_text(s.root() / "off" / "summary.json"), "\"residual_tolerance\": null"));

  // Steps of 0.02 s: the plan diverges (NaN at t = 0.2 s) and, unchecked, first records a
  // residual of 0.72; checked, it ends before the first sample beyond the tolerance.
  const fs::path div = variant(s, "diverging.yaml", "step: 1e-3", "step: 0.02");
  r = run(s, "plan " + quote(div) + " -q -o " + quote(s.root() / "div"));
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_TRUE(contains(r.err, "residual_tolerance")) << describe(r);
  EXPECT_LE(max_abs_column(read_text(s.root() / "div" / "plan.csv"), "phi_"), 1e-3);
  const fs::path div_off = variant(s, "diverging_off.yaml", "step: 1e-3", "step: 0.02, residual_tolerance: none");
  r = run(s, "plan " + quote(div_off) + " -q -o " + quote(s.root() / "div_off"));
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_TRUE(contains(r.err, "not finite")) << describe(r);
  EXPECT_GT(max_abs_column(read_text(s.root() / "div_off" / "plan.csv"), "phi_"), 0.1);

  // A step longer than the span is no plan at all: a located error (exit 2).
  const fs::path big = variant(s, "big.yaml", "step: 1e-3", "step: 1");
  r = run(s, "plan " + quote(big) + " -q -o " + quote(s.root() / "big"));
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(one_error_line(r, big.string() + ":35: integrator.step: the step 1 s is longer than the time span"))
      << describe(r);
}

TEST(Trust, TrackingAPlanThatLeftTheWorkspaceIsNeverASuccess) {
  Scratch s;
  const fs::path f = kStoppedDir / "planar_3r_leaves_workspace.yaml";
  const fs::path out = s.root() / "out";
  const Result r = run(s, "track " + quote(f) + " -q -o " + quote(out) + " --report");
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_TRUE(contains(r.err, "refdyn: error: the plan stopped early: at t = ")) << describe(r);
  EXPECT_TRUE(contains(r.err, "refdyn: error: 40 of 40 runs tracked the plan only up to where it stopped")) << describe(r);
  EXPECT_EQ(count_lines(r.err), 2) << "one line for the plan, one for its runs" << describe(r);
  const std::string summary = read_text(out / "summary.json");
  EXPECT_TRUE(contains(summary, "\"status\": \"residual above tolerance\"")) << summary.substr(0, 800);
  EXPECT_EQ(count_of(summary, "\"status\": \"success\""), 0u);
  EXPECT_EQ(count_of(summary, "\"status\": \"reference stopped early\""), 40u);
  EXPECT_TRUE(contains(summary, "\"completed\": 0,")) << summary.substr(summary.find("\"statistics\""), 200);
  // The plan holds only trustworthy samples: no exploding values, its constraints within 1e-3.
  const std::string plan = read_text(out / "plan.csv");
  EXPECT_LE(max_abs_column(plan, "phi_"), 1e-3);
  EXPECT_LT(max_abs_column(plan, "q_"), 10.0);
  const auto plan_lines = lines_of(plan);
  const double t_end = std::strtod(csv_cells(plan_lines.back()).at(0).c_str(), nullptr);
  EXPECT_GT(t_end, 0.5);
  EXPECT_LT(t_end, 2.0);
  // Every run: its status, its time (the plan's end) and the reason, in sweep.csv.
  const refdyn::io::CsvText sweep = refdyn::io::parse_csv(read_text(out / "sweep.csv"), "sweep.csv");
  ASSERT_EQ(sweep.rows.size(), 40u);
  ASSERT_EQ(sweep.header.back(), "message");
  const int t_col = sweep.column("t_end");
  ASSERT_GE(t_col, 0);
  for (const auto& cells : sweep.rows) {
    EXPECT_EQ(cells[2], "reference stopped early") << cells[1];
    EXPECT_NEAR(std::strtod(cells[t_col].c_str(), nullptr), t_end, 1e-9) << cells[1];
    EXPECT_TRUE(contains(cells.back(), "where the plan stopped (residual above tolerance")) << cells.back();
  }
  // summary.json read back (nlohmann): every run's status and end time.
  const refdyn::JsonValue js = refdyn::parse_json(summary, "summary.json");
  ASSERT_EQ(js["runs"].size(), 40u);
  for (const auto& run : js["runs"]) {
    EXPECT_EQ(run["status"], "reference stopped early");
    EXPECT_NEAR(run["t_end"].get<double>(), t_end, 1e-9);
  }
  EXPECT_EQ(js["statistics"]["completed"], 0);
  const std::string report = read_text(out / "report.html");
  EXPECT_TRUE(contains(report, "reference stopped early"));  // from summary.json, shown in the runs table
}

TEST(Trust, CheckSaysWhichNormTheConditionNumberUses) {
  Scratch s;
  const Result r = run(s, "check " + quote(kGood));
  EXPECT_EQ(r.code, 0) << describe(r);
  EXPECT_TRUE(contains(r.out, "cond(K_dc) = ")) << describe(r);
  EXPECT_TRUE(contains(r.out, "(1-norm: ||A||_1 ||K_dc^-1||_1")) << describe(r);
  EXPECT_TRUE(contains(r.out, "the plan stops where max |Phi| > 0.001 (integrator.residual_tolerance)")) << describe(r);
}

}  // namespace

namespace {
using refdyn::json_text;
using refdyn::JsonValue;
using refdyn::parse_json;

/// The data object a report page carries (<script id="refdyn-data">).
JsonValue report_data(const fs::path& html) {
  const std::string page = read_text(html);
  const std::string open = "<script type=\"application/json\" id=\"refdyn-data\">";
  const size_t a = page.find(open);
  const size_t b = page.find("</script>", a);
  if (a == std::string::npos || b == std::string::npos) return JsonValue();
  return parse_json(page.substr(a + open.size(), b - a - open.size()), html.string());
}
}  // namespace

// The report shows what was recorded (issue 20): the partition as summary.json recorded it when
// the plan was made, each constraint's order and the task geometry as the problem recorded them
// when it was built. Nothing is re-run: an edited summary.json shows in the page.
TEST(Report, ShowsRecordedPartitionOrdersAndGeometry) {
  Scratch s;
  const fs::path dir = s.root() / "paper";
  Result r = run(s, "plan " + quote(kSource / "examples/paper/paper.yaml") + " -q -o " + quote(dir) + " --report");
  ASSERT_EQ(r.code, 0) << describe(r);
  const JsonValue summary = parse_json(read_text(dir / "summary.json"), "summary.json");
  const JsonValue& part = summary["plan"]["partition_t0"];
  ASSERT_TRUE(part.is_object()) << json_text(summary["plan"]);
  EXPECT_EQ(part["independent"], JsonValue::parse(R"(["psi1"])"));
  EXPECT_EQ(part["dependent"], JsonValue::parse(R"(["psi2", "z3"])"));
  EXPECT_GT(part["condition"].get<double>(), 1.0);
  EXPECT_EQ(part["used_by_solver"], true) << "3 coordinates, 2 rows: the partitioned basis";
  JsonValue data = report_data(dir / "report.html");
  ASSERT_TRUE(data.is_object());
  const JsonValue& sc = data["scenario"];
  EXPECT_EQ(sc["partition"]["independent"], part["independent"]);
  EXPECT_EQ(sc["partition"]["condition_t0"], part["condition"]);
  ASSERT_EQ(sc["ellipses"].size(), 1u) << json_text(sc["ellipses"]);
  const JsonValue& e = sc["ellipses"][0];
  EXPECT_EQ(e["point"], "E");
  // The numbers of the built constraint, the same as its equation's text.
  const std::string eq = sc["constraints"][0]["equation"].get<std::string>();
  for (const char* k : {"a", "b"}) EXPECT_TRUE(contains(eq, json_text(e[k], 0))) << eq << " " << k;
  EXPECT_EQ(sc["constraints"][0]["order"], "holonomic (position)");

  // Edit the recorded partition: `refdyn report` shows the edit (it does not plan again).
  JsonValue edited = summary;
  edited["plan"]["partition_t0"]["independent"] = JsonValue::parse(R"(["z3"])");
  std::ofstream(dir / "summary.json") << json_text(edited, 2, 2) << "\n";
  r = run(s, "report " + quote(dir) + " -q");
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_EQ(report_data(dir / "report.html")["scenario"]["partition"]["independent"], JsonValue::parse(R"(["z3"])"));
  // Results without a recorded partition (an older refdyn): the page says nothing about it.
  edited["plan"].erase("partition_t0");
  std::ofstream(dir / "summary.json") << json_text(edited, 2, 2) << "\n";
  r = run(s, "report " + quote(dir) + " -q");
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_TRUE(report_data(dir / "report.html")["scenario"]["partition"].is_null());

  // Acceleration-level rows are labelled by their order (they were all "holonomic" before).
  const fs::path tray = s.root() / "tray";
  r = run(s, "plan " + quote(kSource / "examples/waiter_tray/waiter_tray.yaml") + " -q -o " + quote(tray) + " --report");
  ASSERT_EQ(r.code, 0) << describe(r);
  const JsonValue tray_data = report_data(tray / "report.html");
  std::set<std::string> orders;
  for (const JsonValue& c : tray_data["scenario"]["constraints"]) orders.insert(c["order"].get<std::string>());
  EXPECT_TRUE(orders.count("acceleration (order 2)")) << json_text(tray_data["scenario"]["constraints"]);
}

// ---------------------------------------------------------------------------------------------
// plan --sensitivity (docs/sensitivity.md)

TEST(Sensitivity, PlanWritesTheTableAndTheMetricGradients) {
  Scratch s;
  const fs::path tray = kSource / "examples/waiter_tray/waiter_tray.yaml", out = s.root() / "out";
  const Result r = run(s, "plan " + quote(tray) + " -o " + quote(out) + " --sensitivity 'T, swing'");
  ASSERT_EQ(r.code, 0) << describe(r);
  EXPECT_TRUE(contains(r.out, "sensitivities to 2 parameters")) << describe(r);
  const refdyn::io::CsvTable plan = refdyn::io::read_csv_numbers((out / "plan.csv").string());
  const refdyn::io::CsvTable table = refdyn::io::read_csv_numbers((out / "sensitivity.csv").string());
  ASSERT_EQ(table.rows.size(), plan.rows.size());
  const auto col = [&](const std::string& name) {
    const auto it = std::find(table.header.begin(), table.header.end(), name);
    EXPECT_NE(it, table.header.end()) << name;
    return static_cast<size_t>(it - table.header.begin());
  };
  const size_t dq1 = col("dq_q1/dT"), dreq2 = col("drequired_q2/dswing");
  col("dqdd_q2/dT");
  col("dphi_no_slip_on_tray/dswing");
  const refdyn::JsonValue js = refdyn::parse_json(read_text(out / "sensitivity.json"), "sensitivity.json");
  EXPECT_EQ(js["parameters"]["T"].get<double>(), 2.0);
  std::map<std::string, refdyn::JsonValue> metrics;
  for (const auto& m : js["metrics"]) metrics[m["name"].get<std::string>()] = m;
  // The table and the metrics tell the same: the final q1 and the peak elbow effort.
  EXPECT_EQ(metrics.at("final_q(q1)")["gradient"]["T"].get<double>(), table.rows.back()[dq1]);
  const refdyn::JsonValue& peak = metrics.at("peak_effort(q2)");
  const double t_peak = peak["t"].get<double>();
  size_t k = 0;
  while (k < table.rows.size() && table.rows[k][0] != t_peak) ++k;
  ASSERT_LT(k, table.rows.size());
  const double required = plan.rows[k][static_cast<size_t>(std::find(plan.header.begin(), plan.header.end(), "required_q2") -
                                                           plan.header.begin())];
  EXPECT_EQ(peak["gradient"]["swing"].get<double>(), (required < 0 ? -1 : 1) * table.rows[k][dreq2]);
}

TEST(Sensitivity, UnknownParameterOrAFamilyIsRejectedBeforeAnythingIsWritten) {
  Scratch s;
  const fs::path tray = kSource / "examples/waiter_tray/waiter_tray.yaml", out = s.root() / "out";
  Result r = run(s, "plan " + quote(tray) + " -o " + quote(out) + " --sensitivity Tx");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_EQ(count_lines(r.err), 1) << describe(r);
  EXPECT_TRUE(contains(r.err, "did you mean 'T'")) << describe(r);
  EXPECT_FALSE(fs::exists(out));
  r = run(s, "plan " + quote(tray) + " -o " + quote(out) + " --sensitivity T,,swing");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_FALSE(fs::exists(out));
  const fs::path family = kSource / "examples/planar_2r_circle/family.yaml";
  r = run(s, "plan " + quote(family) + " -o " + quote(out) + " --sensitivity R");
  EXPECT_EQ(r.code, 2) << describe(r);
  EXPECT_TRUE(contains(r.err, "not for a family of variants")) << describe(r);
  EXPECT_FALSE(fs::exists(out));
}

// ---------------------------------------------------------------------------------------------
// The partition and its condition number at t0 (issue 33, item 4): the same, real κ = cond(K_dc)
// in check's text, summary.json and the report whatever the solver. Under the Lagrange solver
// (the default from kLagrangeFrom = 16 coordinates) the KKT solve uses no partition, and neither
// does the projection's orthonormal basis (this 7-coordinate arm); what is shown is the one the
// projection solver takes, and each says so.

namespace {

/// examples/urdf_arm_line with its URDF path made absolute, a 1 s plan and `extra` appended.
fs::path arm_line_scenario(const Scratch& s, const std::string& name, const std::string& extra) {
  std::string text = read_text(kSource / "examples/urdf_arm_line/urdf_arm_line.yaml");
  auto replace = [&](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  };
  replace("file: ../urdf/arm7.urdf", "file: '" + (kSource / "examples/urdf/arm7.urdf").string() + "'");
  replace("t1: 12,", "t1: 1,");
  const fs::path p = s.root() / name;
  std::ofstream(p) << text << extra;
  return p;
}

/// The number check prints after "cond(K_dc) = ", as printed.
std::string printed_condition(const std::string& out) {
  const std::string key = "cond(K_dc) = ";
  const size_t a = out.find(key);
  if (a == std::string::npos) return "";
  return out.substr(a + key.size(), out.find(' ', a + key.size()) - a - key.size());
}

std::string sig6(double v) {
  std::ostringstream os;  // check_text's formatting (std::ostream, 6 significant digits)
  os << v;
  return os.str();
}

}  // namespace

// Without constraint rows there is nothing to partition: check says so, and summary.json
// records used_by_solver false.
TEST(Partition, NoRowsNothingToPartition) {
  Scratch s;
  const fs::path file = kGoodDir / "free_one_dof.yaml";
  const Result c = run(s, "check " + quote(file));
  ASSERT_EQ(c.code, 0) << describe(c);
  EXPECT_TRUE(contains(c.out, "(no constraint rows: nothing to partition)")) << describe(c);
  EXPECT_FALSE(contains(c.out, "uses no partition")) << describe(c);
  const fs::path dir = s.root() / "out";
  const Result r = run(s, "plan " + quote(file) + " -q -o " + quote(dir));
  ASSERT_EQ(r.code, 0) << describe(r);
  const JsonValue summary = parse_json(read_text(dir / "summary.json"), "summary.json");
  EXPECT_EQ(summary["plan"]["partition_t0"]["used_by_solver"], false);
}

TEST(Partition, LagrangeAndProjectionReportTheSameRealConditionNumber) {
  Scratch s;
  const fs::path lagrange = arm_line_scenario(s, "lagrange.yaml", "\nsolver: lagrange\n"),
                 projection = arm_line_scenario(s, "projection.yaml", "\nsolver: projection\n");
  const Result ca = run(s, "check " + quote(lagrange)), cp = run(s, "check " + quote(projection));
  ASSERT_EQ(ca.code, 0) << describe(ca);
  ASSERT_EQ(cp.code, 0) << describe(cp);
  const std::string ka = printed_condition(ca.out), kp = printed_condition(cp.out);
  EXPECT_EQ(ka, kp) << describe(ca) << describe(cp);
  ASSERT_FALSE(ka.empty()) << describe(ca);
  EXPECT_GT(std::stod(ka), 1.0) << "a 7-coordinate arm with 3 rows is not perfectly conditioned" << describe(ca);
  // The partition printed is the same; the Lagrange one says that its solve does not use it.
  auto partition_line = [](const std::string& out) {
    const size_t a = out.find("partition: independent [");
    return a == std::string::npos ? std::string() : out.substr(a, out.find('\n', a) - a);
  };
  EXPECT_EQ(partition_line(ca.out), partition_line(cp.out));
  EXPECT_FALSE(contains(partition_line(ca.out), "independent [], dependent []")) << describe(ca);
  EXPECT_TRUE(contains(ca.out, "(solver lagrange: the KKT solve uses no partition")) << describe(ca);
  EXPECT_TRUE(contains(cp.out, "(solver projection: at this size its orthonormal null-space solve uses no partition"))
      << describe(cp);

  // summary.json and the report record the same numbers as check printed.
  std::map<std::string, JsonValue> recorded;
  for (const auto& [name, file] : {std::pair<std::string, fs::path>{"lagrange", lagrange}, {"projection", projection}}) {
    const fs::path dir = s.root() / ("out_" + name);
    const Result r = run(s, "plan " + quote(file) + " -q -o " + quote(dir) + " --report");
    ASSERT_EQ(r.code, 0) << describe(r);
    const JsonValue summary = parse_json(read_text(dir / "summary.json"), "summary.json");
    const JsonValue& part = summary["plan"]["partition_t0"];
    ASSERT_TRUE(part.is_object()) << name << ": " << json_text(summary["plan"]);
    EXPECT_EQ(sig6(part["condition"].get<double>()), ka) << name;
    EXPECT_EQ(part["used_by_solver"], false) << name << ": neither solve uses it at 7 coordinates";
    EXPECT_EQ(part["automatic"], true) << name;
    const JsonValue data = report_data(dir / "report.html");
    ASSERT_TRUE(data.is_object()) << name;
    const JsonValue& shown = data["scenario"]["partition"];
    EXPECT_EQ(shown["condition_t0"], part["condition"]) << name;
    EXPECT_EQ(shown["independent"], part["independent"]) << name;
    EXPECT_EQ(shown["used_by_solver"], part["used_by_solver"]) << name;
    EXPECT_EQ(data["scenario"]["solver"]["solver"], name == "projection" ? "projection" : "lagrange") << name;
    recorded[name] = part;
  }
  // Bit for bit: the Lagrange plan records the projection solver's partition at t0.
  EXPECT_EQ(recorded["lagrange"]["condition"], recorded["projection"]["condition"]);
  EXPECT_EQ(recorded["lagrange"]["independent"], recorded["projection"]["independent"]);
  EXPECT_EQ(recorded["lagrange"]["dependent"], recorded["projection"]["dependent"]);
}

// "(chosen automatically)" (the partition at t0, partition.independent: auto) and the solver
// table's partition column (which also says whether automatic_switch re-chooses it) come from
// the same setting; they once read "(chosen automatically)" beside "automatic partition: no".
TEST(Report, PartitionChoiceAgreesBetweenCheckThePartitionLineAndTheSolverTable) {
  Scratch s;
  struct Case {
    fs::path file;
    bool automatic, switching;
  };
  const std::vector<Case> cases{{arm_line_scenario(s, "auto.yaml", ""), true, true},
                                {arm_line_scenario(s, "auto_kept.yaml", "") , true, false},
                                {kGood, false, false}};
  {  // auto_kept.yaml: the same task without automatic_switch
    std::string t = read_text(cases[1].file);
    t.replace(t.find("  automatic_switch: true\n"), std::string("  automatic_switch: true\n").size(), "");
    std::ofstream(cases[1].file) << t;
  }
  for (const Case& c : cases) {
    const Result ch = run(s, "check " + quote(c.file));
    ASSERT_EQ(ch.code, 0) << describe(ch);
    EXPECT_EQ(contains(ch.out, "(chosen automatically)"), c.automatic) << describe(ch);
    const fs::path dir = s.root() / ("out_" + c.file.stem().string());
    const Result r = run(s, "plan " + quote(c.file) + " -q -o " + quote(dir) + " --report");
    ASSERT_EQ(r.code, 0) << describe(r);
    const JsonValue data = report_data(dir / "report.html");
    const JsonValue& sc = data["scenario"];
    EXPECT_EQ(sc["partition"]["automatic"], c.automatic) << c.file;
    EXPECT_EQ(sc["solver"]["partition_automatic"], c.automatic) << c.file;
    EXPECT_EQ(sc["solver"]["partition_switch"], c.switching) << c.file;
    EXPECT_FALSE(sc["solver"].contains("automatic_partition")) << json_text(sc["solver"]);
    EXPECT_FALSE(contains(read_text(dir / "report.html"), "'automatic partition'")) << c.file;
  }
}

// ---------------------------------------------------------------------------------------------
// plan --require-feasible: exit 4 after writing the results when the verdict is not feasible.

TEST(Plan, RequireFeasibleExitsFourAfterWritingTheResults) {
  Scratch s;
  // The minimal arm with an effort limit on the shoulder that its task exceeds.
  std::string text = read_text(kGood);
  const std::string j1 = "inertia: [0.01, 0.05, 0.05]}";
  ASSERT_TRUE(contains(text, j1));
  text.replace(text.find(j1), j1.size(), "inertia: [0.01, 0.05, 0.05], limits: {effort: 1e-6}}");
  const fs::path infeasible = s.root() / "infeasible.yaml";
  std::ofstream(infeasible) << text;

  const fs::path plain = s.root() / "plain", strict = s.root() / "strict", good = s.root() / "good";
  Result r = run(s, "plan " + quote(infeasible) + " -q -o " + quote(plain));
  EXPECT_EQ(r.code, 0) << "without the flag a plan that is not feasible still exits 0" << describe(r);
  const JsonValue verdict = parse_json(read_text(plain / "feasibility.json"), "feasibility.json");
  ASSERT_EQ(verdict["feasible"], false) << json_text(verdict);

  r = run(s, "plan " + quote(infeasible) + " -q -o " + quote(strict) + " --require-feasible");
  EXPECT_EQ(r.code, 4) << describe(r);
  EXPECT_EQ(count_lines(r.err), 1) << describe(r);
  EXPECT_TRUE(contains(r.err, "the plan is not feasible (1 violation: j1 effort")) << describe(r);
  EXPECT_TRUE(contains(r.err, "--require-feasible")) << describe(r);
  EXPECT_TRUE(r.out.empty()) << describe(r);
  // The outputs are written as usual, identical to the run without the flag (but for wall times).
  for (const char* f : {"plan.csv", "feasibility.json"}) EXPECT_EQ(read_text(strict / f), read_text(plain / f)) << f;
  EXPECT_TRUE(fs::exists(strict / "summary.json"));

  r = run(s, "plan " + quote(kGood) + " -q -o " + quote(good) + " --require-feasible");
  EXPECT_EQ(r.code, 0) << "a feasible plan passes" << describe(r);
  EXPECT_TRUE(r.err.empty()) << describe(r);
}

// A task that fixes every coordinate (m = n): no independent coordinates, every one dependent,
// and κ = ‖A‖₁ ‖A⁻¹‖₁ — under the Lagrange solver too (it printed "independent [], dependent []"
// and cond 1).
TEST(Partition, ATaskFixingEveryCoordinateHasAllDependentUnderEitherSolver) {
  Scratch s;
  std::string text = read_text(kGood);
  const std::string given = "partition:\n  independent: [j2]\n";
  ASSERT_TRUE(contains(text, given));
  text.replace(text.find(given), given.size(), "partition:\n  independent: auto\n");
  const std::string constraints = "constraints:\n";
  text.insert(text.find(constraints) + constraints.size(), "  - name: tip_y\n    expression: y(E) - L2\n");
  std::map<std::string, std::string> lines;
  for (const char* solver : {"lagrange", "projection"}) {
    const fs::path f = s.root() / (std::string(solver) + ".yaml");
    std::ofstream(f) << text << "\nsolver: " << solver << "\n";
    const Result r = run(s, "check " + quote(f));
    ASSERT_EQ(r.code, 0) << describe(r);
    const size_t a = r.out.find("partition: independent [");
    ASSERT_NE(a, std::string::npos) << describe(r);
    lines[solver] = r.out.substr(a, r.out.find('\n', a) - a);
    EXPECT_TRUE(contains(lines[solver], "partition: independent [], dependent [j1, j2] (chosen automatically)"))
        << describe(r);
    EXPECT_GE(std::stod(printed_condition(r.out)), 1.0) << describe(r);
  }
  EXPECT_EQ(lines["lagrange"], lines["projection"]);
}
