// Families of tasks (src/io/variants.cpp): a variant is exactly the scenario with its
// parameters rewritten (checked against the rewritten YAML, bit for bit); threads and shards
// give the bits of one thread; invalid variants are reported and do not stop the others; the
// section's errors name their key.
#include "refdyn/io/csv.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/variants.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

using namespace refdyn;
namespace fs = std::filesystem;

namespace {

// The planar 2R circle example (fully prescribed motion, projected initial velocity) with a
// shorter span, and the `variants:` section `extra`.
std::string circle(const std::string& extra, const std::string& R = "0.15") {
  std::string text = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/planar_2r_circle.yaml");
  text = std::regex_replace(text, std::regex("t1: 4\\}"), "t1: 0.5}");
  text = std::regex_replace(text, std::regex("R: 0.15 "), "R: " + R + " ");
  return text + "\n" + extra;
}

const std::string kGrid = R"(variants:
  name: "R{R}_T{Tp}"
  grid: {R: [0.1, 0.2], Tp: [1, 2, 3]}
)";

fs::path temp_dir(const std::string& what) {
  const fs::path d = fs::temp_directory_path() / ("refdyn_variants_" + what + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  return d;
}

int cli(const std::string& args) {
  const int status = std::system((std::string(REFDYN_CLI) + " " + args + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST(Variants, GridExpandsRowMajorWithNamesAndValues) {
  const ScenarioSpec spec = io::parse_scenario(circle(kGrid), "family.yaml");
  const auto v = io::expand_variants(spec);
  ASSERT_EQ(v.size(), 6u);
  const char* names[] = {"R0.1_T1", "R0.1_T2", "R0.1_T3", "R0.2_T1", "R0.2_T2", "R0.2_T3"};
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(v[i].name, names[i]);
    ASSERT_EQ(v[i].values.size(), 2u);
    EXPECT_EQ(v[i].values[0], (std::pair<std::string, double>{"R", i < 3 ? 0.1 : 0.2}));
    EXPECT_EQ(v[i].values[1], (std::pair<std::string, double>{"Tp", static_cast<double>(i % 3 + 1)}));
  }
  // No section: no variants.
  EXPECT_TRUE(io::expand_variants(io::parse_scenario(circle(""), "one.yaml")).empty());
}

// A variant is the scenario with R rewritten: its plan equals the plan of that file, bit for bit
// (and the parameters after R, which use it — v0, ex0, q10, q20 — follow).
TEST(Variants, AVariantIsTheScenarioWithItsParametersRewritten) {
  const ScenarioSpec spec = io::parse_scenario(circle(kGrid), "family.yaml");
  const auto v = io::expand_variants(spec);
  const auto from_variant = build_problem(io::variant_spec(spec, v[4]));  // R = 0.2, Tp = 2
  const auto written = io::parse_problem(circle("", "0.2"), "written.yaml");
  EXPECT_EQ(from_variant->parameters, written->parameters);
  EXPECT_EQ(from_variant->q0, written->q0);
  io::RunOptions o;
  const io::Results a = io::run_problem(*from_variant, o), b = io::run_problem(*written, o);
  ASSERT_TRUE(a.plan.summary.ok());
  EXPECT_EQ(io::trajectory_table(a.plan).to_string(), io::trajectory_table(b.plan).to_string());
}

// The override carries the number itself: a value with no short decimal text (0.1 + 0.2 − 0.15 = 0.15000000000000005) reaches
// the Problem bit for bit, the written text of the parameter stays as written, and the
// parameters after it (which use it) follow.
TEST(Variants, TheOverrideCarriesTheNumber) {
  const ScenarioSpec spec = io::parse_scenario(circle(kGrid), "family.yaml");
  io::Variant v;
  v.name = "odd";
  const double R = 0.1 + 0.2 - 0.15;
  v.values = {{"R", R}};
  const ScenarioSpec s = io::variant_spec(spec, v);
  ASSERT_EQ(s.parameter_values.count("R"), 1u);
  EXPECT_EQ(s.parameter_values.at("R").value, R);
  EXPECT_EQ(s.parameter_values.at("R").text, "0.15000000000000005");
  EXPECT_GT(s.parameter_values.at("R").where.line, 0);
  const auto written = std::find_if(s.parameters.begin(), s.parameters.end(), [](const auto& p) { return p.first == "R"; });
  ASSERT_NE(written, s.parameters.end());
  EXPECT_EQ(written->second.text, std::find_if(spec.parameters.begin(), spec.parameters.end(), [](const auto& p) {
                                    return p.first == "R";
                                  })->second.text);
  const auto p = build_problem(s);
  EXPECT_EQ(p->parameters.at("R"), R);
  const auto direct = io::parse_problem(circle("", "0.15000000000000005"), "written.yaml");
  EXPECT_EQ(p->parameters, direct->parameters);
}

TEST(Variants, ThreadsAndShardsGiveTheBitsOfOneThread) {
  const ScenarioSpec spec = io::parse_scenario(circle(kGrid), "family.yaml");
  const auto v = io::expand_variants(spec);
  const fs::path d1 = temp_dir("j1"), d3 = temp_dir("j3");
  io::VariantOptions o;
  o.dir = d1;
  o.jobs = 1;
  const auto one = io::run_variants(spec, v, o);
  o.dir = d3;
  o.jobs = 3;
  const auto three = io::run_variants(spec, v, o);
  const std::vector<std::string> joints{"q1", "q2"};
  EXPECT_EQ(io::variants_csv(joints, v, three, false), io::variants_csv(joints, v, one, false));
  for (const auto& x : v)
    for (const char* f : {"plan.csv", "feasibility.json"})
      EXPECT_EQ(test::read_file(d3 / x.name / f), test::read_file(d1 / x.name / f)) << x.name << "/" << f;
  // Two shards split the variants; together they give the same rows.
  io::VariantOptions s;
  s.num_shards = 2;
  s.shard = 0;
  auto merged = io::run_variants(spec, v, s);
  s.shard = 1;
  const auto other = io::run_variants(spec, v, s);
  for (size_t i = 0; i < v.size(); ++i) {
    EXPECT_NE(merged[i].done, other[i].done);
    if (other[i].done) merged[i] = other[i];
  }
  EXPECT_EQ(io::variants_csv(joints, v, merged, false), io::variants_csv(joints, v, one, false));
  // Each folder holds its own variant: at t0 (same position, velocity projected onto the speed
  // 2πR/Tp) the joint speeds of R = 0.2, Tp = 1 are three times those of Tp = 3.
  auto first_qd1 = [&](const std::string& name) {
    const io::CsvTable t = io::read_csv_numbers((d1 / name / "plan.csv").string());
    for (size_t c = 0; c < t.header.size(); ++c)
      if (t.header[c] == "qd_q1") return t.rows.at(0)[c];
    return std::nan("");
  };
  const double fast = first_qd1("R0.2_T1"), slow = first_qd1("R0.2_T3");
  EXPECT_NE(slow, 0);
  EXPECT_NEAR(fast, 3 * slow, 1e-9 * std::abs(fast));
  fs::remove_all(d1);
  fs::remove_all(d3);
}

// A variant whose initial state violates a constraint (the paper's ellipse with another a,
// `consistency: check`) is reported as invalid with the error; the others are planned.
TEST(Variants, AnInvalidVariantIsReportedAndTheOthersRun) {
  std::string text = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/examples/paper/paper.yaml");
  text = std::regex_replace(text, std::regex("t1: 5, residual_from: 0.5"), "t1: 0.2, residual_from: 0.1");
  text = std::regex_replace(text, std::regex("\nexperiments:[\\s\\S]*?\noutputs:"), "\noutputs:");
  text += "\nvariants:\n  name: \"z{z0}\"\n  sweep: {z0: [h1 + 0.5*sin(45*deg), 0.6]}\n";
  const ScenarioSpec spec = io::parse_scenario(text, "paper_family.yaml");
  const auto v = io::expand_variants(spec);
  ASSERT_EQ(v.size(), 2u);
  const auto s = io::run_variants(spec, v, {});
  EXPECT_TRUE(s[0].ok()) << s[0].error << s[0].message;
  EXPECT_TRUE(s[0].feasible);
  EXPECT_FALSE(s[1].ok());
  EXPECT_NE(s[1].error.find("violates constraint"), std::string::npos) << s[1].error;
  const std::string csv = io::variants_csv({"psi1", "psi2", "z3"}, v, s, false);
  EXPECT_NE(csv.find("\n1,z0.6,invalid,0.6,"), std::string::npos) << csv;
  const std::string js = json_text(io::variants_summary_json("p", "f", {"psi1", "psi2", "z3"}, v, s, false, 0), 2, 2);
  EXPECT_NE(js.find("\"valid\": 1,"), std::string::npos) << js;
}

TEST(Variants, SectionErrorsNameTheKey) {
  auto fails = [](const std::string& section, const std::vector<std::string>& needles) {
    test::expect_error_mentioning(
        [&] { io::expand_variants(io::parse_scenario(circle(section), "bad.yaml")); }, needles);
  };
  fails("variants: {grid: {Rr: [1, 2]}}\n", {"bad.yaml:", "variants.grid.Rr", "no parameter 'Rr'", "did you mean 'R'"});
  fails("variants: {sweep: {R: []}}\n", {"variants.sweep.R", "non-empty list"});
  fails("variants: {sweep: {R: [1]}, grid: {Tp: [1]}}\n", {"variants.grid", "one of sweep and grid"});
  fails("variants: {name: same, sweep: {R: [0.1, 0.2]}}\n", {"variants.name", "two variants are named 'same'"});
  fails("variants: {name: \"a/{R}\", sweep: {R: [0.1]}}\n", {"variants.name", "variant name"});
  fails("variants: {sweep: {R: [0.1, 0.2, 0.3]}}\nlimits: {max_runs: 2}\n", {"variants", "3 variants", "max_runs = 2"});
  fails("variants: {sweep: {R: [1, x]}}\n", {"variants.sweep.R"});
  fails("variants: {grid: {R: [0.1]}, names: x}\n", {"variants.names", "unknown key"});
}

TEST(Variants, CommandLineWritesTheAggregateAndOneFolderPerVariant) {
  const fs::path base = temp_dir("cli");
  fs::create_directories(base);
  const fs::path scenario = base / "family.yaml";
  std::ofstream(scenario) << circle(kGrid);
  ASSERT_EQ(cli("plan " + scenario.string() + " -o " + (base / "j1").string() + " -q -j 1"), 0);
  ASSERT_EQ(cli("plan " + scenario.string() + " -o " + (base / "j2").string() + " -q -j 2"), 0);
  EXPECT_EQ(test::read_file(base / "j1" / "variants.csv"), test::read_file(base / "j2" / "variants.csv"));
  EXPECT_TRUE(fs::exists(base / "j1" / "R0.2_T3" / "plan.csv"));
  EXPECT_NE(test::read_file(base / "j1" / "summary.json").find("\"feasible\": 6,"), std::string::npos);
  ASSERT_EQ(cli("plan " + scenario.string() + " -o " + (base / "none").string() + " -q --run-csv none"), 0);
  EXPECT_FALSE(fs::exists(base / "none" / "R0.2_T3"));
  EXPECT_EQ(test::read_file(base / "none" / "variants.csv"), test::read_file(base / "j1" / "variants.csv"));
  EXPECT_EQ(cli("plan " + scenario.string() + " -o " + (base / "rep").string() + " -q --report"), 2);
  EXPECT_FALSE(fs::exists(base / "rep"));
  fs::remove_all(base);
}

// examples/planar_2r_circle/family.yaml: every variant's end effector runs on its own circle,
// |E − C| = R of that variant, at its own speed 2πR/Tp (closed form of the task).
TEST(Variants, TheFamilyExampleDrawsEachVariantsCircleAtItsSpeed) {
  const ScenarioSpec spec = io::load_scenario(std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/family.yaml");
  const auto v = io::expand_variants(spec);
  ASSERT_EQ(v.size(), 6u);
  for (const io::Variant& x : v) {
    const auto p = build_problem(io::variant_spec(spec, x));
    const double R = p->parameters.at("R"), Tp = p->parameters.at("Tp");
    EXPECT_EQ(R, x.values[0].second);
    EXPECT_EQ(Tp, x.values[1].second);
    const io::Results r = io::run_problem(*p);
    ASSERT_TRUE(r.plan.summary.ok()) << x.name;
    const Trajectory& t = r.plan;
    double worst_r = 0, worst_v = 0;
    for (size_t k = 1; k + 1 < t.size(); k += 97) {
      const Eigen::Vector3d e = t.point_positions[k].head<3>();
      worst_r = std::max(worst_r, std::abs(std::hypot(e.x() - 0.6, e.y() - 0.2) - R));
      const Eigen::Vector3d d = (t.point_positions[k + 1].head<3>() - t.point_positions[k - 1].head<3>()) /
                                (t.t[k + 1] - t.t[k - 1]);  // central difference of E
      worst_v = std::max(worst_v, std::abs(d.norm() - 2 * M_PI * R / Tp));
    }
    EXPECT_LT(worst_r, 1e-8) << x.name;
    EXPECT_LT(worst_v, 1e-5) << x.name << " (finite-difference speed)";
  }
}
