// The field descriptions of the result structs (common/fields.hpp): JSON written from them reads
// back (nlohmann) into an equal struct, CSV headers are the fields' columns, the JSON text
// format (json_text) and the one CSV reader (io::parse_csv).
#include "refdyn/common/error.hpp"
#include "refdyn/common/fields_json.hpp"
#include "refdyn/io/csv.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/variants.hpp"
#include "refdyn/simulate/feasibility.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <utility>

using namespace refdyn;

namespace {

/// Equal as the bits that survive a JSON round trip: the same number, or both NaN.
void expect_same(double a, double b, const std::string& what) {
  if (std::isnan(a)) EXPECT_TRUE(std::isnan(b)) << what;
  else EXPECT_EQ(a, b) << what;
}

io::RunSummary sample_run() {
  io::RunSummary s;
  s.status = IntegrationStatus::StepSizeCollapse;
  s.message = "stopped at t = 0.1: \"quoted\", comma\nand a line";
  s.t_end = 0.1 + 0.2;  // not a short decimal
  s.steps = 1234;
  s.saturated_samples = 7;
  s.final_max_abs_error = 1e-300;
  s.peak_abs_tau = 12.5;
  s.joints = {{0.25, std::nan(""), 3e-7, 12.5}, {1.0 / 3.0, 0.75, 0, 2}};
  s.wall_time = 0.125;
  return s;
}

/// Optional and named values (what the check report's JSON and Python dict are made of).
struct Inner {
  double a = 0;
  long b = 0;
};
struct Outer {
  int order = 0;
  std::optional<double> kept, omitted;
  std::optional<Inner> inner;
  std::vector<std::pair<std::string, double>> named;
  std::vector<std::pair<std::string, Inner>> named_inner;
};

}  // namespace

template <>
struct refdyn::Fields<Inner> {
  static constexpr auto list() { return std::make_tuple(field("a", &Inner::a), field("b", &Inner::b)); }
};
template <>
struct refdyn::Fields<Outer> {
  static constexpr auto list() {
    return std::make_tuple(field("order", &Outer::order), field("kept", &Outer::kept),
                           field("omitted", &Outer::omitted) | OmitIfEmpty{}, field("inner", &Outer::inner),
                           field("named", &Outer::named), field("named_inner", &Outer::named_inner));
  }
};

// An empty optional is null, or no key at all with OmitIfEmpty; named values are an object in
// their order (of numbers or of structs); int reads back. Everything round-trips.
TEST(Fields, OptionalAndNamedValues) {
  Outer o;
  o.order = 3;
  o.named = {{"z", 1.5}, {"a", -2}};
  o.named_inner = {{"q2", {0.5, 7}}, {"q1", {0.25, -1}}};
  JsonValue j = to_json(o);
  EXPECT_EQ(json_text(j, 0), R"({"order": 3, "kept": null, "inner": null, "named": {"z": 1.5, "a": -2}, )"
                             R"("named_inner": {"q2": {"a": 0.5, "b": 7}, "q1": {"a": 0.25, "b": -1}}})");
  o.kept = 0.1 + 0.2;
  o.omitted = 4;
  o.inner = Inner{1e-300, 9};
  j = to_json(o);
  EXPECT_TRUE(j.contains("omitted"));
  const Outer r = from_json<Outer>(parse_json(json_text(j), "test"));
  EXPECT_EQ(r.order, 3);
  ASSERT_TRUE(r.kept && r.omitted && r.inner);
  EXPECT_EQ(*r.kept, 0.1 + 0.2);
  EXPECT_EQ(*r.omitted, 4.0);
  EXPECT_EQ(r.inner->a, 1e-300);
  EXPECT_EQ(r.inner->b, 9);
  EXPECT_EQ(r.named, o.named);
  ASSERT_EQ(r.named_inner.size(), 2u);
  EXPECT_EQ(r.named_inner[0].first, "q2");
  EXPECT_EQ(r.named_inner[1].second.b, -1);
}

TEST(Fields, RunSummaryJsonRoundTrip) {
  const io::RunSummary s = sample_run();
  const std::vector<std::string> joints = {"psi1", "psi2"};
  FieldContext c;
  c.names = &joints;
  c.late = "2.5";
  const std::string text = json_text(to_json(s, c), 2, 2);
  EXPECT_NE(text.find("\"max_abs_error_after_2.5s\": 3e-07"), std::string::npos) << text;
  EXPECT_NE(text.find("\"joint\": \"psi2\""), std::string::npos) << text;
  EXPECT_EQ(text.find("\"steps\""), std::string::npos) << "steps go to MPI and Python, not to summary.json";
  const io::RunSummary r = from_json<io::RunSummary>(parse_json(text, "test"), c);
  EXPECT_EQ(r.status, s.status);
  EXPECT_EQ(r.message, s.message);
  EXPECT_EQ(r.t_end, s.t_end);
  EXPECT_EQ(r.steps, 0);  // not in JSON
  EXPECT_EQ(r.saturated_samples, s.saturated_samples);
  EXPECT_EQ(r.final_max_abs_error, s.final_max_abs_error);
  EXPECT_EQ(r.peak_abs_tau, s.peak_abs_tau);
  EXPECT_EQ(r.wall_time, s.wall_time);
  ASSERT_EQ(r.joints.size(), s.joints.size());
  for (size_t j = 0; j < s.joints.size(); ++j) {
    expect_same(r.joints[j].e0, s.joints[j].e0, "e0");
    expect_same(r.joints[j].settle_time, s.joints[j].settle_time, "settle_time (NaN: null)");
    expect_same(r.joints[j].late_error, s.joints[j].late_error, "late_error");
    expect_same(r.joints[j].peak_tau, s.joints[j].peak_tau, "peak_tau");
  }
  // Every field that goes to JSON is read back: writing the read struct gives the same text.
  EXPECT_EQ(json_text(to_json(r, c), 2, 2), text);
}

TEST(Fields, VariantSummaryJsonRoundTrip) {
  io::VariantSummary s;
  s.done = true;
  s.status = IntegrationStatus::ResidualExceeded;
  s.message = "ψ₁ residual";
  s.t_end = 2.75;
  s.max_constraint_residual = 1.5e-9;
  s.feasible = true;
  s.violations = 3;
  s.peak_speed = {1, 2};
  s.runs = 4;
  s.runs_completed = 3;
  s.worst_final_error = 0.1;
  s.worst_peak_tau = std::numeric_limits<double>::infinity();  // written as null
  s.wall_time = 9;
  FieldContext c;
  c.holds = when::Tracked | when::Ran | when::HasRuns;
  const JsonValue j = parse_json(json_text(to_json(s, c), 0), "test");
  EXPECT_EQ(j.size(), 10u) << json_text(j, 0);  // message … worst_peak_abs_tau, wall_time_s
  const io::VariantSummary r = from_json<io::VariantSummary>(j, c);
  EXPECT_EQ(r.message, s.message);
  EXPECT_EQ(r.t_end, s.t_end);
  EXPECT_EQ(r.max_constraint_residual, s.max_constraint_residual);
  EXPECT_EQ(r.feasible, s.feasible);
  EXPECT_EQ(r.violations, s.violations);
  EXPECT_EQ(r.runs, s.runs);
  EXPECT_EQ(r.runs_completed, s.runs_completed);
  EXPECT_EQ(r.worst_final_error, s.worst_final_error);
  EXPECT_TRUE(std::isnan(r.worst_peak_tau)) << "non-finite numbers are null";
  EXPECT_EQ(r.wall_time, s.wall_time);
  // Without runs tracked the run fields are not written.
  FieldContext untracked;
  EXPECT_FALSE(to_json(s, untracked).contains("runs"));
}

TEST(Fields, PlanSummaryAndFeasibilityJsonRoundTrip) {
  IntegrationSummary s;
  s.status = IntegrationStatus::MaxSteps;
  s.message = "m";
  s.steps = 10;
  s.rejected_steps = 2;
  s.rhs_evaluations = 99;
  s.jacobian_evaluations = 7;
  s.newton_failures = 3;
  s.max_projection_correction = 1.0 / 3.0;
  s.t_end = 1.0 / 7.0;
  s.max_constraint_residual = 2e-12;
  s.wall_time = 0.5;
  const IntegrationSummary r = from_json<IntegrationSummary>(parse_json(json_text(to_json(s)), "test"));
  EXPECT_EQ(r.status, s.status);
  EXPECT_EQ(r.message, s.message);
  EXPECT_EQ(r.steps, s.steps);
  EXPECT_EQ(r.rejected_steps, s.rejected_steps);
  EXPECT_EQ(r.rhs_evaluations, s.rhs_evaluations);  // the solver counters are in summary.json (issue 21)
  EXPECT_EQ(r.jacobian_evaluations, s.jacobian_evaluations);
  EXPECT_EQ(r.newton_failures, s.newton_failures);
  EXPECT_EQ(r.max_projection_correction, s.max_projection_correction);
  EXPECT_EQ(r.t_end, s.t_end);
  EXPECT_EQ(r.max_constraint_residual, s.max_constraint_residual);
  EXPECT_EQ(r.wall_time, s.wall_time);

  FeasibilityReport f;
  JointFeasibility jf;
  jf.joint = "q1";
  jf.q_min = -0.5, jf.q_max = 1.25, jf.peak_speed = 3, jf.t_peak_speed = 0.1;
  jf.peak_acceleration = 4, jf.t_peak_acceleration = 0.2, jf.peak_effort = 5, jf.t_peak_effort = 0.3;
  jf.limits.velocity = 2;
  f.joints = {jf};
  f.violations = {{"q1", "velocity", 2, 3, {{0.05, 0.15}, {0.5, 0.75}}}};
  f.complete = false;
  f.incomplete_reason = "stopped";
  const std::string text = f.json();
  EXPECT_EQ(text.rfind("{\"feasible\": false, \"incomplete_reason\": \"stopped\", \"joints\": [{\"joint\": \"q1\", "
                       "\"q_min\": -0.5, \"q_max\": 1.25, \"peak_speed\": 3, \"t_peak_speed\": 0.1, ", 0),
            0u)
      << text;
  EXPECT_NE(text.find("\"limits\": {\"lower\": null, \"upper\": null, \"velocity\": 2, \"effort\": null}"),
            std::string::npos)
      << text;
  FieldContext c;
  c.holds = when::Incomplete;
  const FeasibilityReport g = from_json<FeasibilityReport>(parse_json(text, "feasibility.json"), c);
  EXPECT_EQ(g.incomplete_reason, "stopped");
  ASSERT_EQ(g.joints.size(), 1u);
  EXPECT_EQ(g.joints[0].q_max, 1.25);
  EXPECT_EQ(g.joints[0].t_peak_effort, 0.3);
  EXPECT_EQ(g.joints[0].limits.velocity, 2);
  EXPECT_TRUE(std::isnan(g.joints[0].limits.lower)) << "an infinite limit is null in JSON";
  ASSERT_EQ(g.violations.size(), 1u);
  EXPECT_EQ(g.violations[0].intervals, f.violations[0].intervals);
  EXPECT_EQ(g.violations[0].quantity, "velocity");
}

TEST(Fields, CsvColumnsAreTheFieldsColumns) {
  const std::vector<std::string> joints = {"a", "b"};
  FieldContext c;
  c.names = &joints;
  std::vector<std::string> cols;
  io::csv_columns<io::RunSummary>(cols, c);
  EXPECT_EQ(cols, (std::vector<std::string>{"t_end", "final_max_abs_error", "peak_abs_tau", "max_e0", "max_settle_time",
                                            "max_late_error", "saturated_samples", "e0_a", "e0_b", "settle_a", "settle_b",
                                            "late_a", "late_b", "peak_tau_a", "peak_tau_b", "message"}));
  // Each column is a field's column (or <column>_<joint>), every field marked for CSV has one.
  size_t csv_fields = 0;
  for_each_field<io::RunSummary>([&](const auto& f) {
    if (!(f.in & sink::Csv)) return;
    ++csv_fields;
    const std::string col = f.column();
    bool found = false;
    for (const auto& x : cols) found = found || x == col;
    if (col == "joints") {
      for_each_field<io::JointTracking>([&](const auto& g) {
        EXPECT_NE(std::find(cols.begin(), cols.end(), std::string(g.column()) + "_b"), cols.end()) << g.column();
      });
    } else {
      EXPECT_TRUE(found) << col;
    }
  });
  EXPECT_EQ(csv_fields, 9u);
  std::vector<std::string> cells;
  io::csv_cells(cells, sample_run(), c);
  ASSERT_EQ(cells.size(), cols.size());
  EXPECT_EQ(cells.back(), "\"stopped at t = 0.1: \"\"quoted\"\", comma\nand a line\"");
  EXPECT_EQ(cells[0], "0.30000000000000004");
  EXPECT_EQ(cells[4], "0.75") << "max_settle_time: the largest finite settle time";
  EXPECT_EQ(cells[9], "nan") << "settle_a";

  cols.clear();
  c.holds = when::Tracked;
  io::csv_columns<io::VariantSummary>(cols, c);
  EXPECT_EQ(cols, (std::vector<std::string>{"t_end", "max_constraint_residual", "feasible", "violations",
                                            "peak_speed_a", "peak_speed_b", "peak_effort_a", "peak_effort_b", "runs",
                                            "runs_completed", "worst_final_max_abs_error", "worst_peak_abs_tau"}));
  cells.clear();
  io::VariantSummary invalid;  // not run: the outcome cells are empty ("nan" for numbers)
  io::csv_cells(cells, invalid, c);
  EXPECT_EQ(cells, (std::vector<std::string>{"nan", "nan", "", "", "nan", "nan", "nan", "nan", "0", "0", "nan", "nan"}));

  // The whole table read back by the one CSV reader: header and cells as written.
  std::vector<io::Variant> variants = {{"v0", {{"R", 0.5}}, -1}, {"v1", {{"R", 1}}, -1}};
  std::vector<io::VariantSummary> summaries(2);
  summaries[0].done = true;
  summaries[0].t_end = 1;
  summaries[0].peak_speed = {1, 2};
  summaries[0].peak_effort = {3, 4};
  summaries[1].done = true;
  summaries[1].error = "x.yaml:3: bad, \"value\"";
  const io::CsvText t = io::parse_csv(io::variants_csv(joints, variants, summaries, true), "variants.csv");
  EXPECT_EQ(std::vector<std::string>(t.header.begin() + 4, t.header.end()), cols);
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.rows[0][t.column("peak_effort_b")], "4");
  EXPECT_EQ(t.rows[1][t.column("status")], "invalid");
  EXPECT_EQ(t.rows[1][t.column("feasible")], "");
}

TEST(Fields, JsonTextFormat) {
  JsonValue v = JsonValue::object();
  v["n"] = 0.1;
  v["i"] = 3;
  v["u"] = static_cast<unsigned long>(18446744073709551615ul);
  v["x"] = std::nan("");
  v["b"] = true;
  v["s"] = std::string("a\"b\\\n\x01\x7f\xff");
  v["a"] = JsonValue::array();
  v["a"].push_back(1.0);
  v["a"].push_back(JsonValue::object());
  v["a"][1]["deep"] = JsonValue::array();
  v["a"][1]["deep"].push_back(1e21);
  v["e"] = JsonValue::array();
  EXPECT_EQ(json_text(v, 2, 2),
            "{\n  \"n\": 0.1,\n  \"i\": 3,\n  \"u\": 18446744073709551615,\n  \"x\": null,\n  \"b\": true,\n"
            "  \"s\": \"a\\\"b\\\\\\n\\u0001\\u007f\\ufffd\",\n  \"a\": [\n    1,\n    {\"deep\": [1e+21]}\n  ],\n"
            "  \"e\": []\n}");
  EXPECT_EQ(json_text(v["a"], 0), "[1, {\"deep\": [1e+21]}]");
  EXPECT_EQ(json_text(v["a"], -1), "[1,{\"deep\":[1e+21]}]");  // minimal: the report's data
  EXPECT_EQ(parse_json(json_text(v, -1), "minimal"), parse_json(json_text(v, 2, 2), "pretty"));
  EXPECT_THROW(parse_json("{\"a\": }", "f.json"), Error);
  try {
    parse_json("{\"a\": 1,\n \"b\" 2}", "f.json");
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("f.json: not valid JSON (parse error at line 2", 0), 0u) << e.what();
  }
}

TEST(Fields, OneCsvReader) {
  const io::CsvText t = io::parse_csv("a,b,c\r\n1,\"x,\"\"y\"\"\",\n\n2,\"two\nlines\",z\n", "t.csv");
  EXPECT_EQ(t.header, (std::vector<std::string>{"a", "b", "c"}));
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.rows[0], (std::vector<std::string>{"1", "x,\"y\"", ""}));
  EXPECT_EQ(t.rows[1], (std::vector<std::string>{"2", "two\nlines", "z"}));
  EXPECT_EQ(t.lines, (std::vector<size_t>{2, 4}));
  try {
    io::parse_csv("a,b\n1,2\n3\n", "t.csv");
    ADD_FAILURE() << "a short row";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "t.csv:3: expected 2 values, got 1");
  }
  const io::CsvTable n = io::parse_csv_numbers("t,q\n0,nan\n0.5,-1e-3\n", "n.csv");
  ASSERT_EQ(n.rows.size(), 2u);
  EXPECT_TRUE(std::isnan(n.rows[0][1]));
  EXPECT_EQ(n.rows[1][1], -1e-3);
  try {
    io::parse_csv_numbers("t,q\n0,1\n0.5,x\n", "n.csv");
    ADD_FAILURE() << "a word";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "n.csv:3: expected numbers separated by commas");
  }
}
