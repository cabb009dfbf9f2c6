// Running a Problem (src/io/results.cpp): experiments on a thread pool or spread over shards
// (the MPI ranks' share) give the same bits as one thread; streamed per-run tables equal the
// kept trajectories; the sweep statistics' percentiles equal hand-computed ones; the CLI's
// --jobs and --run-csv write the files one thread writes.
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/common/text.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace refdyn;
namespace fs = std::filesystem;

namespace {

const std::string kScenario = std::string(REFDYN_SOURCE_DIR) + "/tests/data/good/sweep_arm.yaml";

io::Results run(const Problem& p, int jobs, size_t keep = std::numeric_limits<size_t>::max(), int shard = 0,
                int shards = 1, const fs::path& csv_dir = {}) {
  io::RunOptions o;
  o.track = true;
  o.jobs = jobs;
  o.keep_trajectories = keep;
  o.shard = shard;
  o.num_shards = shards;
  o.run_csv_dir = csv_dir;
  return io::run_problem(p, o);
}

void expect_same_trajectory(const ClosedLoopResult& a, const ClosedLoopResult& b, const std::string& name) {
  ASSERT_EQ(a.t.size(), b.t.size()) << name;
  ASSERT_GT(a.t.size(), 10u) << name;
  for (size_t k = 0; k < a.t.size(); ++k) {
    ASSERT_EQ(a.t[k], b.t[k]) << name << " sample " << k;
    ASSERT_EQ(a.x[k], b.x[k]) << name << " sample " << k;
    ASSERT_EQ(a.tau[k], b.tau[k]) << name << " sample " << k;
  }
  EXPECT_EQ(a.summary.steps, b.summary.steps) << name;
}

void expect_same_summary(const io::RunSummary& a, const io::RunSummary& b, const std::string& name) {
  EXPECT_EQ(a.status, b.status) << name;
  EXPECT_EQ(a.message, b.message) << name;
  EXPECT_EQ(a.t_end, b.t_end) << name;
  EXPECT_EQ(a.steps, b.steps) << name;
  EXPECT_EQ(a.final_max_abs_error, b.final_max_abs_error) << name;
  EXPECT_EQ(a.peak_abs_tau, b.peak_abs_tau) << name;
  ASSERT_EQ(a.joints.size(), b.joints.size()) << name;
  for (size_t j = 0; j < a.joints.size(); ++j) {
    EXPECT_EQ(a.joints[j].e0, b.joints[j].e0) << name;
    // NaN (no settle time) equals NaN here: compare the bits.
    EXPECT_EQ(std::isnan(a.joints[j].settle_time), std::isnan(b.joints[j].settle_time)) << name;
    if (!std::isnan(a.joints[j].settle_time)) {
      EXPECT_EQ(a.joints[j].settle_time, b.joints[j].settle_time) << name;
    }
    EXPECT_EQ(a.joints[j].late_error, b.joints[j].late_error) << name;
    EXPECT_EQ(a.joints[j].peak_tau, b.joints[j].peak_tau) << name;
  }
}

/// summary.json without its wall-time lines (the only thing that differs between executions).
std::string without_wall_times(const std::string& json) {
  std::istringstream in(json);
  std::string line, out;
  while (std::getline(in, line)) {
    std::string::size_type at;
    while ((at = line.find("\"wall_time_s\": ")) != std::string::npos) {
      const auto end = line.find_first_of(",}", at);
      line.erase(at, end - at);
    }
    out += line + "\n";
  }
  return out;
}

int cli(const std::string& args) {
  const std::string cmd = std::string(REFDYN_CLI) + " " + args + " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Threads and shards: the same bits as one thread.
TEST(ParallelRuns, ThreadsGiveTheBitsOfOneThread) {
  const auto p = io::load_problem(kScenario);
  ASSERT_EQ(p->experiments.size(), 6u);
  const io::Results serial = run(*p, 1);
  ASSERT_TRUE(serial.ok());
  for (int jobs : {2, 3, 6}) {
    const io::Results par = run(*p, jobs);
    ASSERT_EQ(par.runs.size(), serial.runs.size());
    for (size_t i = 0; i < serial.runs.size(); ++i) {
      const std::string name = serial.runs[i].experiment->name + " with " + std::to_string(jobs) + " threads";
      EXPECT_TRUE(par.runs[i].done);
      expect_same_trajectory(par.runs[i].result, serial.runs[i].result, name);
      expect_same_summary(par.runs[i].summary, serial.runs[i].summary, name);
    }
    EXPECT_EQ(io::sweep_csv(*p, par), io::sweep_csv(*p, serial));
    EXPECT_EQ(without_wall_times(json_text(io::summary_json(*p, par), 2, 2)),
              without_wall_times(json_text(io::summary_json(*p, serial), 2, 2)));
  }
}

// A run's numbers depend on its experiment only: run alone (the last shard of six holds just
// the last experiment) it gives what it gives after five others (each run has its own
// reference dynamics; with an automatic partition a shared one would carry state over).
TEST(ParallelRuns, ARunAloneEqualsTheSameRunInTheSweep) {
  const auto p = io::load_problem(kScenario);
  ASSERT_TRUE(p->automatic_independent);
  ASSERT_EQ(p->integrator.method, IntegratorMethod::DormandPrince45);  // the reference is integrated per run
  const io::Results all = run(*p, 1);
  const io::Results alone = run(*p, 1, std::numeric_limits<size_t>::max(), 5, 6);
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_FALSE(alone.runs[i].done);
    EXPECT_TRUE(alone.runs[i].result.t.empty());
  }
  ASSERT_TRUE(alone.runs[5].done);
  expect_same_trajectory(alone.runs[5].result, all.runs[5].result, "damped alone");
}

// Two shards (two MPI ranks) split the runs; together they hold the serial summaries.
TEST(ParallelRuns, ShardsSplitTheRunsAndTogetherGiveTheSerialSummaries) {
  const auto p = io::load_problem(kScenario);
  const io::Results serial = run(*p, 1, 0);
  const io::Results s0 = run(*p, 2, 0, 0, 2), s1 = run(*p, 1, 0, 1, 2);
  for (size_t i = 0; i < serial.runs.size(); ++i) {
    EXPECT_NE(s0.runs[i].done, s1.runs[i].done) << "run " << i << " in exactly one shard";
    EXPECT_EQ(s0.runs[i].done, i % 2 == 0);
    const io::Results& mine = s0.runs[i].done ? s0 : s1;
    expect_same_summary(mine.runs[i].summary, serial.runs[i].summary, serial.runs[i].experiment->name);
    EXPECT_TRUE(mine.runs[i].result.t.empty()) << "keep_trajectories = 0 keeps no trajectory";
  }
  // Invalid shards are an error, not an empty result.
  test::expect_error_mentioning([&] { run(*p, 1, 0, 2, 2); }, {"shard 2 of 2"});
  test::expect_error_mentioning([&] { run(*p, 1, 0, 0, 0); }, {"shard 0 of 0"});
}

// Streamed tables (written as each run ends, trajectories dropped) equal the kept ones.
TEST(ParallelRuns, StreamedRunTablesEqualTheKeptTrajectories) {
  const auto p = io::load_problem(kScenario);
  const fs::path dir = fs::temp_directory_path() / ("refdyn_results_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  io::prepare_output_dir(dir);
  const io::Results kept = run(*p, 1);
  const io::Results streamed = run(*p, 2, 2, 0, 1, dir);
  EXPECT_TRUE(streamed.runs_written);
  for (size_t i = 0; i < kept.runs.size(); ++i) {
    const std::string& name = kept.runs[i].experiment->name;
    EXPECT_EQ(test::read_file(dir / ("track_" + name + ".csv")), io::trajectory_table(kept.runs[i].result).to_string()) << name;
    EXPECT_EQ(streamed.runs[i].result.t.empty(), i >= 2) << "the first two trajectories are kept";
  }
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Statistics: percentiles as numpy's default (linear between order statistics).
TEST(SweepStatistics, PercentilesAreLinearBetweenOrderStatistics) {
  // Sorted: 1 2 3 4; position f·(n − 1): p25 at 0.75 → 1.75, p50 at 1.5 → 2.5, p95 at 2.85 → 3.85.
  const io::Distribution d = io::distribution_of({3, 1, std::nan(""), 4, 2, INFINITY});
  EXPECT_EQ(d.count, 4);
  EXPECT_EQ(d.missing, 2);
  EXPECT_EQ(d.min, 1);
  EXPECT_EQ(d.max, 4);
  EXPECT_DOUBLE_EQ(d.p25, 1.75);
  EXPECT_DOUBLE_EQ(d.p50, 2.5);
  EXPECT_DOUBLE_EQ(d.p75, 3.25);
  EXPECT_DOUBLE_EQ(d.p95, 3.85);
  EXPECT_DOUBLE_EQ(d.p99, 3.97);
  EXPECT_DOUBLE_EQ(d.p5, 1.15);
  EXPECT_DOUBLE_EQ(d.mean, 2.5);
  const io::Distribution one = io::distribution_of({7});
  EXPECT_EQ(one.p5, 7);
  EXPECT_EQ(one.p99, 7);
  const io::Distribution none = io::distribution_of({std::nan("")});
  EXPECT_EQ(none.count, 0);
  EXPECT_EQ(none.missing, 1);
  EXPECT_TRUE(std::isnan(none.p50));
  // 1..101: p_k is k + 1 exactly.
  std::vector<double> v;
  for (int i = 101; i >= 1; --i) v.push_back(i);
  const io::Distribution h = io::distribution_of(v);
  EXPECT_EQ(h.p5, 6);
  EXPECT_EQ(h.p50, 51);
  EXPECT_EQ(h.p95, 96);
  EXPECT_EQ(h.mean, 51);
}

TEST(SweepStatistics, SweepCsvHasOneRowPerRunAndTheSweepValues) {
  const auto p = io::load_problem(kScenario);
  const io::Results r = run(*p, 2, 0);
  const std::string csv = io::sweep_csv(*p, r);
  std::istringstream in(csv);
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("index,name,status,d,t_end,final_max_abs_error,peak_abs_tau,", 0), 0u) << header;
  EXPECT_NE(header.find(",peak_tau_j2"), std::string::npos);
  std::vector<std::string> rows;
  while (std::getline(in, line)) rows.push_back(line);
  ASSERT_EQ(rows.size(), 6u);
  EXPECT_EQ(rows[0].rfind("0,d-0.2,success,-0.2,0.6,", 0), 0u) << rows[0];
  EXPECT_EQ(rows[5].rfind("5,damped,success,,0.6,", 0), 0u) << rows[5] << " (no sweep value: empty cell)";
  // The statistics summarize the same per-run numbers.
  const JsonValue s = io::summary_json(*p, r);
  const std::string js = json_text(s, 2, 2);
  const std::string st = js.substr(js.find("\"statistics\""));
  for (const char* key : {"\"runs\": 6,", "\"completed\": 6,", "\"stopped_early\": 0,"})
    EXPECT_NE(st.find(key), std::string::npos) << key << " not in " << st.substr(0, 300);
  std::vector<double> peaks;
  for (const auto& rr : r.runs) peaks.push_back(rr.summary.peak_abs_tau);
  const io::Distribution d = io::distribution_of(peaks);
  const std::string peak = st.substr(st.find("\"peak_abs_tau\""));
  EXPECT_EQ(peak.find("\"p50\": " + fmt(d.p50)), peak.find("\"p50\"")) << peak.substr(0, 300);
}

// ---------------------------------------------------------------------------------------------
// The command line: --jobs and --run-csv.
TEST(ParallelRuns, CommandLineJobsWriteTheFilesOfOneThread) {
  const fs::path base = fs::temp_directory_path() / ("refdyn_jobs_test_" + std::to_string(::getpid()));
  fs::remove_all(base);
  ASSERT_EQ(cli("track " + kScenario + " -o " + (base / "j1").string() + " -q -j 1"), 0);
  ASSERT_EQ(cli("track " + kScenario + " -o " + (base / "j2").string() + " -q --jobs 2"), 0);
  int files = 0;
  for (const auto& e : fs::directory_iterator(base / "j1")) {
    const std::string f = e.path().filename().string();
    ++files;
    if (f == "summary.json")
      EXPECT_EQ(without_wall_times(test::read_file(e.path())), without_wall_times(test::read_file(base / "j2" / f)));
    else
      EXPECT_EQ(test::read_file(e.path()), test::read_file(base / "j2" / f)) << f;
  }
  EXPECT_EQ(files, 4 + 6) << "plan.csv, feasibility.json, sweep.csv, summary.json and six track_*.csv";
  // --run-csv none: the aggregate only.
  ASSERT_EQ(cli("track " + kScenario + " -o " + (base / "none").string() + " -q --run-csv none"), 0);
  EXPECT_FALSE(fs::exists(base / "none" / "track_damped.csv"));
  EXPECT_EQ(test::read_file(base / "none" / "sweep.csv"), test::read_file(base / "j1" / "sweep.csv"));
  EXPECT_NE(test::read_file(base / "none" / "summary.json").find("\"track_csv\": false"), std::string::npos);
  // Bad values: one line, exit 1 (command line), nothing written.
  EXPECT_EQ(cli("track " + kScenario + " -o " + (base / "bad").string() + " --run-csv some"), 1);
  EXPECT_EQ(cli("track " + kScenario + " -o " + (base / "bad").string() + " --jobs -2"), 1);
  EXPECT_FALSE(fs::exists(base / "bad"));
  fs::remove_all(base);
}

// The pool itself: every index of the shard exactly once, `after` serialized and counting, the
// exception of the smallest failing index rethrown whatever the threads did.
TEST(ParallelRuns, ForEachIndexVisitsTheShardOnceAndRethrowsTheFirstFailure) {
  for (int jobs : {1, 2, 4}) {
    std::vector<std::atomic<int>> hits(103);
    size_t last_done = 0;
    io::for_each_index(hits.size(), 1, 3, jobs, [&](size_t i) { ++hits[i]; },
                       [&](size_t done, size_t total, size_t) {
                         EXPECT_EQ(done, last_done + 1);
                         EXPECT_EQ(total, 34u);
                         last_done = done;
                       });
    EXPECT_EQ(last_done, 34u);
    for (size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(hits[i], i % 3 == 1 ? 1 : 0) << i << " with " << jobs << " jobs";
    // Indices 40 and 70 fail; with one thread 70 is never reached; with more, 40 is reported.
    test::expect_error_mentioning(
        [&] {
          io::for_each_index(100, 0, 1, jobs, [](size_t i) {
            if (i == 40 || i == 70) throw Error("index " + std::to_string(i));
          });
        },
        {"index 40"});
  }
}

// ---------------------------------------------------------------------------------------------
// A plan that leaves its task (issue 24): the sweep scenario with the tip driven out of reach
// (near t = 0.8 s). No run on a plan that stopped early is a success: a run that reaches the
// plan's end says "reference stopped early", with the plan's end as its t_end (summary.json,
// sweep.csv). With RK4 and a tolerance of 1e-4 the plan is cut at its last sample within it.
std::string stopped_scenario(const std::string& method, const std::string& tolerance) {
  std::string text = test::read_file(kScenario);
  auto replace = [&text](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  };
  replace("x(E) - (L1 + 0.1*(1 - cos(2*pi*t))/2)", "x(E) - (L1 + 0.5*t)");
  replace("method: dopri5", "method: " + method);
  replace("t1: 0.6", "t1: 1.2" + (tolerance.empty() ? std::string() : ", residual_tolerance: " + tolerance));
  replace("  q: {j1: 0, j2: 90*deg}", "  q: {j1: 0, j2: 90*deg}\n  consistency: project");
  return text;
}

TEST(StoppedPlan, RunsOnAStoppedPlanAreNeverASuccess) {
  const auto p = io::parse_problem(stopped_scenario("dopri5", ""), "stopped.yaml");
  EXPECT_EQ(p->residual_tolerance, kDefaultResidualTolerance);
  const io::Results r = run(*p, 2);
  const IntegrationSummary& ps = r.plan.summary;
  ASSERT_FALSE(ps.ok());
  EXPECT_GT(ps.t_end, 0.5);
  EXPECT_LT(ps.t_end, 1.2);
  EXPECT_FALSE(r.feasibility.complete);
  ASSERT_EQ(r.runs.size(), 6u);
  int on_stopped_plan = 0;
  for (const auto& run : r.runs) {
    EXPECT_FALSE(run.summary.ok()) << run.experiment->name;
    if (run.summary.status != IntegrationStatus::ReferenceStopped) continue;  // stopped on its own
    ++on_stopped_plan;
    EXPECT_NEAR(run.summary.t_end, ps.t_end, 1e-9) << run.experiment->name;
    EXPECT_NE(run.summary.message.find(std::string("where the plan stopped (") + to_string(ps.status)), std::string::npos)
        << run.summary.message;
  }
  EXPECT_GE(on_stopped_plan, 1);
  EXPECT_NE(json_text(io::summary_json(*p, r), 2, 2).find("\"completed\": 0,"), std::string::npos);
}

TEST(StoppedPlan, Rk4PlanIsCutAtItsLastSampleWithinTheTolerance) {
  const auto p = io::parse_problem(stopped_scenario("rk4", "1e-4"), "stopped.yaml");
  EXPECT_EQ(p->residual_tolerance, 1e-4);
  const io::Results r = run(*p, 2);
  const IntegrationSummary& ps = r.plan.summary;
  ASSERT_EQ(ps.status, IntegrationStatus::ResidualExceeded) << to_string(ps.status) << ": " << ps.message;
  ASSERT_FALSE(r.plan.t.empty());
  EXPECT_EQ(ps.t_end, r.plan.t.back());
  EXPECT_EQ(r.plan.stages.steps, ps.steps);
  EXPECT_NEAR(ps.t_end, ps.steps * r.plan.stages.h, 1e-12);
  for (const auto& phi : r.plan.phi) EXPECT_LE(phi.cwiseAbs().maxCoeff(), 1e-4);
  EXPECT_LE(ps.max_constraint_residual, 1e-4);
  for (const auto& run : r.runs) {
    EXPECT_EQ(run.summary.status, IntegrationStatus::ReferenceStopped) << run.experiment->name << ": " << run.summary.message;
    EXPECT_EQ(run.summary.t_end, ps.t_end) << run.experiment->name;
  }
  const std::string js = json_text(io::summary_json(*p, r), 2, 2);
  EXPECT_NE(js.find("\"residual_tolerance\": " + json_text(JsonValue(1e-4), 0)), std::string::npos) << json_text(JsonValue(1e-4), 0);
  EXPECT_NE(js.find("\"t_end\": " + fmt(ps.t_end)), std::string::npos);
  const std::string csv = io::sweep_csv(*p, r);
  EXPECT_NE(csv.find(",message\n"), std::string::npos);
  EXPECT_NE(csv.find(",reference stopped early,"), std::string::npos);
  EXPECT_NE(csv.find(",\"tracked the reference up to t = "), std::string::npos) << "the message, quoted (it has a comma)";
}
