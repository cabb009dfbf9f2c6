// The main job: the paper's study, i.e. examples/paper/paper.yaml (built into the executable)
// run through the same pipeline as `refdyn track`, plus the study's own summary keys and table.
#include "paper_study_output.hpp"

#include "commands.hpp"
#include "report.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdio>
#include <iostream>

namespace refdyn::app {

extern const char* const kPaperScenarioYaml;  // generated from examples/paper/paper.yaml

namespace {

std::string cell(double x, const char* f = "%9.4f") {
  if (std::isnan(x)) return "        -";
  char b[32];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

double sweep_value(const Experiment& e, const std::string& name) {
  for (const auto& [k, v] : e.sweep)
    if (k == name) return v;
  return std::nan("");
}

}  // namespace

int run_paper_command(const std::string& out, bool quiet, bool report, int jobs) {
  const std::string source = "examples/paper/paper.yaml";
  const auto problem = io::parse_problem(kPaperScenarioYaml, source);
  const Problem& p = *problem;
  io::RunOptions o;
  o.track = true;
  o.progress = terminal_progress(!quiet);
  o.jobs = jobs;
  const io::Results r = io::run_problem(p, o);

  // The study's own keys, on top of the generic summary.
  JsonValue summary = io::summary_json(p, r);
  summary["study"] = "paper three-link manipulator";
  JsonValue& ellipse = summary["ellipse"] = JsonValue::object();
  ellipse["a"] = p.parameters.at("a");
  ellipse["b"] = p.parameters.at("b");
  JsonValue& runs = summary["runs"];
  for (size_t i = 0; i < r.runs.size(); ++i) {
    const Experiment& e = *r.runs[i].experiment;
    runs.at(i)["alpha0_deg"] = sweep_value(e, "alpha0");
    runs.at(i)["plant_friction"] = !e.plant_forces.elements().empty();
  }
  io::write_results(out, p, r, summary);
  if (report) write_report(out, p, r, summary, quiet);

  if (!quiet) {
    const int n = p.model.nv;
    std::cout << "refdyn: the paper's three-link manipulator study (reference from 45 deg; plants from 45, 60, 70, 80 deg)\n";
    std::cout << "plan: " << to_string(r.plan.summary.status) << ", " << r.plan.summary.steps
              << " RK4 steps, max |Phi| over 0.5-5 s = " << r.plan.summary.max_constraint_residual << "\n\n";
    std::cout << r.feasibility.text() << "\n";
    std::cout << "tracking (computed torque + PD, delta = 40, 3, 60 1/s); settle: |e| stays below 1e-3 |e0|\n";
    std::cout << "run               joint   |e0|        settle[s]  max|e| after 2.5 s  peak|tau|\n";
    for (const auto& run : r.runs) {
      const auto& metrics = run.summary.joints;  // io::tracking_metrics(·, 1e-3, middle of the span)
      for (int j = 0; j < n; ++j) {
        char line[200];
        std::snprintf(line, sizeof line, "%-17s %-6s %s  %s  %s          %s\n", j ? "" : run.experiment->name.c_str(),
                      p.model.joint_name[j].c_str(), cell(metrics[j].e0, "%9.4g").c_str(),
                      cell(metrics[j].settle_time).c_str(), cell(metrics[j].late_error, "%9.3g").c_str(),
                      cell(metrics[j].peak_tau, "%9.3f").c_str());
        std::cout << line;
      }
    }
    std::printf("\nstudy wall time %.3f s; results in %s%s\n", r.wall_time, out.c_str(), report ? " (report.html)" : "");
  }
  if (!r.ok()) {
    report_stopped(r);
    return kNumerical;
  }
  return kOk;
}

}  // namespace refdyn::app
