// The main job: the paper's study written as CSV + JSON, with a printed summary table.
#include "paper_study_output.hpp"

#include "refdyn/feasibility.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/kinematics.hpp"
#include "refdyn/models/paper_study.hpp"
#include "refdyn/text.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace refdyn::app {

namespace fs = std::filesystem;
using io::CsvTable;

namespace {

// Illustrative actuator limits for the feasibility report (the paper gives none): a column
// drive of 3 rad/s and 100 N m, an arm joint of 2 rad/s and 50 N m, a slider of 0.5 m/s and 100 N.
void set_illustrative_limits(models::PaperExampleParams& p) {
  const double inf = std::numeric_limits<double>::infinity();
  p.limits = {{-inf, inf, 3.0, 100.0}, {-inf, inf, 2.0, 50.0}, {0.0, 1.0, 0.5, 100.0}};
}

CsvTable plan_table(models::PaperStudy& s, std::vector<Eigen::VectorXd>& required) {
  models::PaperExample& ex = *s.example;
  ReferenceDynamics& rd = *s.rd;
  const Model& m = ex.model;
  const int n = m.nv;
  CsvTable t;
  t.header = {"t"};
  for (const char* pre : {"q_", "qd_", "qdd_"})
    for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
  for (const auto& z : ex.forces.state_names()) t.header.push_back(z);
  for (const char* c : {"E_x", "E_y", "E_z", "z_a"}) t.header.push_back(c);
  for (const char* pre : {"phi_", "phid_"})
    for (int r = 0; r < rd.num_constraints(); ++r) t.header.push_back(pre + ex.constraints.row_name(r));
  t.header.push_back("psi_dr");
  t.header.push_back("tau_drive");
  for (const char* pre : {"Qc_", "required_"})
    for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
  for (int r = 0; r < rd.num_constraints(); ++r) t.header.push_back("lambda_" + ex.constraints.row_name(r));
  const int E = m.point_index("E");
  Eigen::VectorXd dx(rd.state_size());
  for (size_t k = 0; k < s.plan.t.size(); ++k) {
    const double tk = s.plan.t[k];
    const Eigen::VectorXd& x = s.plan.x[k];
    rd.derivative(tk, x, dx);
    std::vector<double> row{tk};
    for (int i = 0; i < 3 * n; ++i) row.push_back(i < 2 * n ? x[i] : dx[n + i - 2 * n]);
    for (int i = 0; i < ex.forces.num_states(); ++i) row.push_back(x[2 * n + i]);
    const Vec3 r = rd.constraints().points[E].r;
    row.insert(row.end(), {r.x(), r.y(), r.z(), ex.z_a->eval(tk).f});
    for (int i = 0; i < rd.num_constraints(); ++i) row.push_back(rd.constraints().phi[i]);
    for (int i = 0; i < rd.num_constraints(); ++i) row.push_back(rd.constraints().phid[i]);
    const Eigen::VectorXd q = x.head(n), qd = x.segment(n, n);
    const double tau_dr = ex.drive ? ex.drive->torque(tk, q, qd) : 0.0;
    row.push_back(ex.drive ? ex.drive->profile().eval(tk).f : 0.0);
    row.push_back(tau_dr);
    Eigen::VectorXd req = rd.constraint_force();
    if (ex.drive) req[ex.drive->joint()] += tau_dr;
    required.push_back(req);
    for (int j = 0; j < n; ++j) row.push_back(rd.constraint_force()[j]);
    for (int j = 0; j < n; ++j) row.push_back(req[j]);
    for (int i = 0; i < rd.num_constraints(); ++i) row.push_back(rd.lambda()[i]);
    t.add_row(std::move(row));
  }
  return t;
}

CsvTable track_table(const Model& m, const ClosedLoopResult& r) {
  const int n = m.nv;
  CsvTable t;
  t.header = {"t"};
  for (const char* pre : {"q_", "qd_", "qref_", "e_", "tau_"})
    for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
  for (const char* c : {"E_x", "E_y", "E_z"}) t.header.push_back(c);
  Data data(m);
  const int E = m.point_index("E");
  for (size_t k = 0; k < r.t.size(); ++k) {
    const Eigen::VectorXd q = r.x[k].head(n);
    std::vector<double> row{r.t[k]};
    for (int j = 0; j < n; ++j) row.push_back(q[j]);
    for (int j = 0; j < n; ++j) row.push_back(r.x[k][n + j]);
    for (int j = 0; j < n; ++j) row.push_back(r.q_ref[k][j]);
    for (int j = 0; j < n; ++j) row.push_back(q[j] - r.q_ref[k][j]);
    for (int j = 0; j < n; ++j) row.push_back(r.tau[k][j]);
    forward_kinematics(m, data, q);
    const Vec3 p = point_position(m, data, E);
    row.insert(row.end(), {p.x(), p.y(), p.z()});
    t.add_row(std::move(row));
  }
  return t;
}

// Time after which |e_j| stays below frac·|e_j(0)|; NaN when e_j(0) = 0 or never.
double settle_time(const ClosedLoopResult& r, int j, double frac) {
  const double e0 = std::abs(r.x[0][j] - r.q_ref[0][j]);
  if (e0 == 0) return std::nan("");
  double ts = std::nan("");
  for (size_t k = r.t.size(); k-- > 0;) {
    if (std::abs(r.x[k][j] - r.q_ref[k][j]) >= frac * e0) break;
    ts = r.t[k];
  }
  return ts;
}

std::string cell(double x, const char* f = "%9.4f") {
  if (std::isnan(x)) return "        -";
  char b[32];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

}  // namespace

int run_paper_command(const std::string& out, bool quiet) {
  const fs::path dir(out);
  io::prepare_output_dir(dir);
  models::PaperStudyOptions opt;
  set_illustrative_limits(opt.example);
  const auto t0 = std::chrono::steady_clock::now();
  models::PaperStudy s = models::run_paper_study(opt);
  const double t_study = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const Model& m = s.example->model;
  const int n = m.nv;

  std::vector<Eigen::VectorXd> required;
  io::write_csv_atomic(dir / "plan.csv", plan_table(s, required));
  for (const auto& run : s.runs) io::write_csv_atomic(dir / ("track_" + run.label + ".csv"), track_table(m, run.result));

  std::vector<Eigen::VectorXd> q, qd;
  for (const auto& x : s.plan.x) q.push_back(x.head(n)), qd.push_back(x.segment(n, n));
  const FeasibilityReport feas = assess_feasibility(m, s.plan.t, q, qd, s.plan.qdd, required);
  io::write_text_atomic(dir / "feasibility.json", feas.json() + "\n");

  // Summary JSON and table.
  std::ostringstream js, tab;
  js << "{\n  \"study\": \"paper three-link manipulator\",\n  \"wall_time_s\": " << io::json_number(t_study)
     << ",\n  \"ellipse\": {\"a\": " << io::json_number(opt.example.ellipse_a) << ", \"b\": "
     << io::json_number(opt.example.ellipse_b) << "},\n  \"plan\": {\"status\": "
     << io::json_string(to_string(s.plan.summary.status)) << ", \"message\": " << io::json_string(s.plan.summary.message)
     << ", \"steps\": " << s.plan.summary.steps << ", \"max_constraint_residual_after_0.5s\": "
     << io::json_number(s.plan.summary.max_constraint_residual) << ", \"wall_time_s\": "
     << io::json_number(s.plan.summary.wall_time) << "},\n  \"feasibility\": " << feas.json() << ",\n  \"runs\": [";
  tab << "run               joint   |e0|        settle[s]  max|e| after 2.5 s  peak|tau|\n";
  for (size_t i = 0; i < s.runs.size(); ++i) {
    const auto& run = s.runs[i];
    const auto& r = run.result;
    js << (i ? "," : "") << "\n    {\"label\": " << io::json_string(run.label) << ", \"alpha0_deg\": "
       << io::json_number(run.alpha0_deg) << ", \"plant_friction\": " << (run.plant_friction ? "true" : "false")
       << ", \"status\": " << io::json_string(to_string(r.summary.status)) << ", \"message\": "
       << io::json_string(r.summary.message) << ", \"saturated_samples\": " << r.saturated_samples << ", \"joints\": [";
    for (int j = 0; j < n; ++j) {
      const double e0 = std::abs(r.x[0][j] - r.q_ref[0][j]);
      const double ts = settle_time(r, j, 1e-3);
      double peak = 0, late = 0;
      for (size_t k = 0; k < r.t.size(); ++k) {
        peak = std::max(peak, std::abs(r.tau[k][j]));
        if (r.t[k] >= 2.5) late = std::max(late, std::abs(r.x[k][j] - r.q_ref[k][j]));
      }
      js << (j ? ", " : "") << "{\"joint\": " << io::json_string(m.joint_name[j]) << ", \"e0\": " << io::json_number(e0)
         << ", \"settle_time_rel_1e-3\": " << io::json_number(ts) << ", \"max_abs_error_after_2.5s\": "
         << io::json_number(late) << ", \"peak_abs_tau\": " << io::json_number(peak) << "}";
      char line[200];
      std::snprintf(line, sizeof line, "%-17s %-6s %s  %s  %s          %s\n", j ? "" : run.label.c_str(),
                    m.joint_name[j].c_str(), cell(e0, "%9.4g").c_str(), cell(ts).c_str(), cell(late, "%9.3g").c_str(),
                    cell(peak, "%9.3f").c_str());
      tab << line;
    }
    js << "], \"wall_time_s\": " << io::json_number(r.summary.wall_time) << "}";
  }
  js << "\n  ]\n}\n";
  io::write_text_atomic(dir / "summary.json", js.str());

  if (!quiet) {
    std::cout << "refdyn: the paper's three-link manipulator study (reference from 45 deg; plants from 45, 60, 70, 80 deg)\n";
    std::cout << "plan: " << to_string(s.plan.summary.status) << ", " << s.plan.summary.steps
              << " RK4 steps, max |Phi| over 0.5-5 s = " << s.plan.summary.max_constraint_residual << "\n\n";
    std::cout << feas.text() << "\n";
    std::cout << "tracking (computed torque + PD, delta = 40, 3, 60 1/s); settle: |e| stays below 1e-3 |e0|\n";
    std::cout << tab.str();
    std::printf("\nstudy wall time %.3f s; results in %s\n", t_study, dir.string().c_str());
  }
  bool ok = s.plan.summary.ok();
  for (const auto& r : s.runs) ok = ok && r.result.summary.ok();
  return ok ? 0 : 4;
}

}  // namespace refdyn::app
