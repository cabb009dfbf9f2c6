// refdyn check / plan / track / plot on scenario files.
#include "commands.hpp"

#include "refdyn/error.hpp"
#include "refdyn/feasibility.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/kinematics.hpp"
#include "refdyn/text.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <unistd.h>

namespace refdyn::app {

namespace fs = std::filesystem;
using io::CsvTable;

namespace {

/// A progress bar on stderr for runs longer than a second (only on a terminal).
class Progress {
 public:
  Progress(std::string what, double t0, double t1, bool enabled = true)
      : what_(std::move(what)), t0_(t0), t1_(t1), start_(clock::now()) {
    tty_ = enabled && ::isatty(STDERR_FILENO);
  }
  void update(double t) {
    if (!tty_ || ++calls_ % 64) return;
    const double el = std::chrono::duration<double>(clock::now() - start_).count();
    if (el < 1.0) return;
    const double f = std::clamp((t - t0_) / (t1_ - t0_), 0.0, 1.0);
    const int w = 30, k = static_cast<int>(f * w);
    std::fprintf(stderr, "\r%s [%s%s] %3.0f%%  t = %.3f s", what_.c_str(), std::string(k, '#').c_str(),
                 std::string(w - k, ' ').c_str(), 100 * f, t);
    shown_ = true;
  }
  ~Progress() {
    if (shown_) std::fprintf(stderr, "\r%s\r", std::string(what_.size() + 60, ' ').c_str());
  }
 private:
  using clock = std::chrono::steady_clock;
  std::string what_;
  double t0_, t1_;
  clock::time_point start_;
  bool tty_ = false, shown_ = false;
  long calls_ = 0;
};

std::string constraint_kind(const Constraint& c) {
  std::string s = to_string(c.origin);
  s += c.first_order() ? ", first-order" : ", holonomic";
  s += c.rheonomic() ? ", rheonomic" : ", scleronomic";
  return s;
}

struct PlannedScenario {
  std::unique_ptr<io::Scenario> sc;
  std::unique_ptr<ReferenceDynamics> rd;
  Plan plan;
};

PlannedScenario plan_scenario(const std::string& file, bool quiet) {
  PlannedScenario p;
  p.sc = io::load_scenario(file);
  io::Scenario& s = *p.sc;
  p.rd = std::make_unique<ReferenceDynamics>(s.model, s.forces, s.constraints, s.options);
  const Eigen::VectorXd x0 = p.rd->make_state(s.q0, s.qd0);
  Progress bar("planning", s.integrator.t0, s.integrator.t1, !quiet);
  p.plan = plan_motion(*p.rd, x0, s.integrator, s.residual_from, [&bar](double t) { bar.update(t); });
  return p;
}

// Required effort: actuator forces + constraint forces.
Eigen::VectorXd required_effort(const io::Scenario& s, ReferenceDynamics& rd, double t, const Eigen::VectorXd& x) {
  const int n = s.model.nv;
  Eigen::VectorXd req = rd.constraint_force();
  const Eigen::VectorXd q = x.head(n), qd = x.segment(n, n);
  for (size_t k = 0; k < s.forces.elements().size(); ++k)
    if (s.forces.elements()[k]->actuator())
      req += s.forces.element_force(static_cast<int>(k), t, q, qd, x.data() + 2 * n);
  return req;
}

CsvTable plan_csv(const io::Scenario& s, ReferenceDynamics& rd, const Plan& plan, std::vector<Eigen::VectorXd>& required) {
  const Model& m = s.model;
  const int n = m.nv, nr = s.constraints.rows();
  CsvTable t;
  t.header = {"t"};
  for (const char* pre : {"q_", "qd_", "qdd_"})
    for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
  for (const auto& z : s.forces.state_names()) t.header.push_back(z);
  for (const auto& p : s.report_points)
    for (const char* a : {"_x", "_y", "_z"}) t.header.push_back(p + a);
  for (const char* pre : {"phi_", "phid_"})
    for (int r = 0; r < nr; ++r) t.header.push_back(pre + s.constraints.row_name(r));
  for (const char* pre : {"Qc_", "required_"})
    for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
  for (int r = 0; r < nr; ++r) t.header.push_back("lambda_" + s.constraints.row_name(r));
  Eigen::VectorXd dx(rd.state_size());
  Data data(m);
  for (size_t k = 0; k < plan.t.size(); ++k) {
    const Eigen::VectorXd& x = plan.x[k];
    std::vector<double> row{plan.t[k]};
    bool ok = true;
    try {
      rd.derivative(plan.t[k], x, dx);
    } catch (const NumericalFailure&) {
      ok = false;
    }
    for (int i = 0; i < 2 * n; ++i) row.push_back(x[i]);
    for (int i = 0; i < n; ++i) row.push_back(ok ? dx[n + i] : NAN);
    for (int i = 0; i < s.forces.num_states(); ++i) row.push_back(x[2 * n + i]);
    forward_kinematics(m, data, x.head(n));
    for (const auto& p : s.report_points) {
      const Vec3 r = point_position(m, data, m.point_index(p));
      row.insert(row.end(), {r.x(), r.y(), r.z()});
    }
    const Eigen::VectorXd req = ok ? required_effort(s, rd, plan.t[k], x) : Eigen::VectorXd::Constant(n, NAN);
    required.push_back(req);
    for (int i = 0; i < nr; ++i) row.push_back(rd.constraints().phi[i]);
    for (int i = 0; i < nr; ++i) row.push_back(rd.constraints().phid[i]);
    for (int j = 0; j < n; ++j) row.push_back(ok ? rd.constraint_force()[j] : NAN);
    for (int j = 0; j < n; ++j) row.push_back(req[j]);
    for (int i = 0; i < nr; ++i) row.push_back(ok ? rd.lambda()[i] : NAN);
    t.add_row(std::move(row));
  }
  return t;
}

std::string summary_json_plan(const io::Scenario& s, const Plan& plan, const FeasibilityReport& f) {
  std::ostringstream js;
  js << "{\n  \"scenario\": " << io::json_string(s.name) << ",\n  \"file\": " << io::json_string(s.file)
     << ",\n  \"plan\": {\"status\": " << io::json_string(to_string(plan.summary.status)) << ", \"message\": "
     << io::json_string(plan.summary.message) << ", \"steps\": " << plan.summary.steps
     << ", \"rejected_steps\": " << plan.summary.rejected_steps << ", \"t_end\": " << io::json_number(plan.summary.t_end)
     << ", \"max_constraint_residual\": " << io::json_number(plan.summary.max_constraint_residual)
     << ", \"wall_time_s\": " << io::json_number(plan.summary.wall_time) << "},\n  \"feasibility\": " << f.json();
  return js.str();
}

FeasibilityReport feasibility_of(const io::Scenario& s, const Plan& plan, const std::vector<Eigen::VectorXd>& required) {
  const int n = s.model.nv;
  std::vector<Eigen::VectorXd> q, qd;
  for (const auto& x : plan.x) q.push_back(x.head(n)), qd.push_back(x.segment(n, n));
  return assess_feasibility(s.model, plan.t, q, qd, plan.qdd, required);
}

void print_plan(const io::Scenario& s, const Plan& plan) {
  std::printf("scenario '%s': %d DOF, %d constraint rows; plan %s, %ld steps, t_end = %.6g s, max |Phi| = %.3g, %.3f s\n",
              s.name.c_str(), s.model.nq, s.constraints.rows(), to_string(plan.summary.status), plan.summary.steps,
              plan.summary.t_end, plan.summary.max_constraint_residual, plan.summary.wall_time);
  if (!plan.summary.ok()) std::printf("  stopped: %s\n", plan.summary.message.c_str());
}

}  // namespace

int run_check(const std::string& file) {
  auto sp = io::load_scenario(file);
  const io::Scenario& s = *sp;
  const Model& m = s.model;
  std::cout << "scenario '" << s.name << "' (" << file << "): valid\n" << m.summary();
  std::cout << "constraints: " << s.constraints.size() << " (" << s.constraints.rows() << " rows)\n";
  int mat = 0, prog = 0, hol = 0, fo = 0;
  for (const auto& c : s.constraints.constraints()) {
    std::cout << "  " << c->name << ": " << constraint_kind(*c) << ": " << c->describe() << "\n";
    (c->origin == ConstraintOrigin::Material ? mat : prog) += c->rows();
    (c->first_order() ? fo : hol) += c->rows();
  }
  std::cout << "  rows by kind: " << mat << " material, " << prog << " programmed; " << hol << " holonomic, " << fo
            << " first-order\n";
  std::cout << "force elements: " << s.forces.elements().size();
  for (const auto& e : s.forces.elements()) std::cout << "  " << e->name();
  std::cout << "\n";
  ReferenceDynamics rd(m, s.forces, s.constraints, s.options);
  Eigen::VectorXd x = rd.make_state(s.q0, s.qd0), dx(x.size());
  rd.derivative(s.integrator.t0, x, dx);
  std::cout << "partition: independent [";
  for (size_t i = 0; i < rd.independent().size(); ++i) std::cout << (i ? ", " : "") << m.joint_name[rd.independent()[i]];
  std::cout << "], dependent [";
  for (size_t i = 0; i < rd.dependent().size(); ++i) std::cout << (i ? ", " : "") << m.joint_name[rd.dependent()[i]];
  std::cout << "]" << (s.automatic_independent ? " (chosen automatically)" : "") << "; cond(K_dc) = "
            << rd.partition_condition() << " at t0\n";
  if (s.project_initial) {
    std::cout << "initial state projected onto the constraints (Newton, dependent coordinates):\n";
    for (int j = 0; j < m.nq; ++j)
      if (s.initial_dq[j] != 0 || s.initial_dqd[j] != 0)
        std::printf("  %-12s q %+.6g -> %.10g   qd %+.6g -> %.10g\n", m.joint_name[j].c_str(), s.initial_dq[j],
                    s.q0[j], s.initial_dqd[j], s.qd0[j]);
  }
  std::cout << "initial residuals at t0 = " << s.integrator.t0 << " s" << (s.project_initial ? " (after projection)" : "")
            << ":\n";
  for (int r = 0; r < s.constraints.rows(); ++r)
    std::printf("  %-20s |Phi| = %.3e   |dPhi/dt| = %.3e\n", s.constraints.row_name(r).c_str(),
                std::abs(rd.constraints().phi[r]), std::abs(rd.constraints().phid[r]));
  std::cout << "integrator: " << to_string(s.integrator.method) << ", step " << s.integrator.step << " s, t = ["
            << s.integrator.t0 << ", " << s.integrator.t1 << "] s\n";
  std::cout << "experiments: " << s.experiments.size() << "\n";
  return kOk;
}

int run_plan(const std::string& file, const std::string& out_dir, bool quiet) {
  PlannedScenario p = plan_scenario(file, quiet);  // validates before anything is written
  io::prepare_output_dir(out_dir);
  std::vector<Eigen::VectorXd> required;
  const CsvTable t = plan_csv(*p.sc, *p.rd, p.plan, required);
  const FeasibilityReport f = feasibility_of(*p.sc, p.plan, required);
  io::write_csv_atomic(fs::path(out_dir) / "plan.csv", t);
  io::write_text_atomic(fs::path(out_dir) / "feasibility.json", f.json() + "\n");
  io::write_text_atomic(fs::path(out_dir) / "summary.json", summary_json_plan(*p.sc, p.plan, f) + "\n}\n");
  if (!quiet) {
    print_plan(*p.sc, p.plan);
    std::cout << f.text() << "results in " << out_dir << "\n";
  }
  return p.plan.summary.ok() ? kOk : kNumerical;
}

int run_track(const std::string& file, const std::string& out_dir, bool quiet) {
  PlannedScenario p = plan_scenario(file, quiet);
  io::Scenario& s = *p.sc;
  if (s.experiments.empty())
    throw Error(file + ": experiments: missing (track needs at least one experiment; see docs/scenario.md)");
  io::prepare_output_dir(out_dir);
  std::vector<Eigen::VectorXd> required;
  io::write_csv_atomic(fs::path(out_dir) / "plan.csv", plan_csv(s, *p.rd, p.plan, required));
  const FeasibilityReport f = feasibility_of(s, p.plan, required);
  io::write_text_atomic(fs::path(out_dir) / "feasibility.json", f.json() + "\n");
  const Model& m = s.model;
  const int n = m.nv;
  std::ostringstream runs;
  bool all_ok = p.plan.summary.ok();
  if (!quiet) print_plan(s, p.plan);
  for (size_t e = 0; e < s.experiments.size(); ++e) {
    const io::Experiment& ex = *s.experiments[e];
    std::unique_ptr<Controller> ctrl;
    if (ex.controller.type == "computed_torque_pd")
      ctrl = std::make_unique<ComputedTorquePD>(m, ex.controller.delta);
    else
      ctrl = std::make_unique<PDGravity>(m, ex.controller.kp, ex.controller.kd);
    ClosedLoopOptions o;
    o.integrator = s.integrator;
    o.integrator.t1 = std::min(s.integrator.t1, p.plan.summary.t_end);
    o.effort_limit = s.effort_limit;
    Progress bar("experiment " + ex.name, o.integrator.t0, o.integrator.t1, !quiet);
    o.progress = [&bar](double t) { bar.update(t); };
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(2 * n + ex.plant_forces.num_states());
    x0.head(n) = ex.q0;
    x0.segment(n, n) = ex.qd0;
    const ClosedLoopResult r = simulate_closed_loop(m, ex.plant_forces, *ctrl, p.plan, p.rd.get(), x0, o);
    all_ok = all_ok && r.summary.ok();
    CsvTable t;
    t.header = {"t"};
    for (const char* pre : {"q_", "qd_", "qref_", "e_", "tau_"})
      for (int j = 0; j < n; ++j) t.header.push_back(pre + m.joint_name[j]);
    for (const auto& pt : s.report_points)
      for (const char* a : {"_x", "_y", "_z"}) t.header.push_back(pt + a);
    Data data(m);
    double peak = 0, last_e = 0;
    for (size_t k = 0; k < r.t.size(); ++k) {
      std::vector<double> row{r.t[k]};
      for (int j = 0; j < 2 * n; ++j) row.push_back(r.x[k][j]);
      for (int j = 0; j < n; ++j) row.push_back(r.q_ref[k][j]);
      for (int j = 0; j < n; ++j) row.push_back(r.x[k][j] - r.q_ref[k][j]);
      for (int j = 0; j < n; ++j) row.push_back(r.tau[k][j]), peak = std::max(peak, std::abs(r.tau[k][j]));
      forward_kinematics(m, data, r.x[k].head(n));
      for (const auto& pt : s.report_points) {
        const Vec3 v = point_position(m, data, m.point_index(pt));
        row.insert(row.end(), {v.x(), v.y(), v.z()});
      }
      t.add_row(std::move(row));
    }
    if (!r.t.empty()) last_e = (r.x.back().head(n) - r.q_ref.back()).cwiseAbs().maxCoeff();
    io::write_csv_atomic(fs::path(out_dir) / ("track_" + ex.name + ".csv"), t);
    runs << (e ? "," : "") << "\n    {\"label\": " << io::json_string(ex.name) << ", \"status\": "
         << io::json_string(to_string(r.summary.status)) << ", \"message\": " << io::json_string(r.summary.message)
         << ", \"final_max_abs_error\": " << io::json_number(last_e) << ", \"peak_abs_tau\": " << io::json_number(peak)
         << ", \"saturated_samples\": " << r.saturated_samples << "}";
    if (!quiet)
      std::printf("  %-24s %s, final max |e| = %.3g, peak |tau| = %.4g%s\n", ex.name.c_str(), to_string(r.summary.status),
                  last_e, peak, r.summary.ok() ? "" : (" (" + r.summary.message + ")").c_str());
  }
  io::write_text_atomic(fs::path(out_dir) / "summary.json",
                        summary_json_plan(s, p.plan, f) + ",\n  \"runs\": [" + runs.str() + "\n  ]\n}\n");
  if (!quiet) std::cout << f.text() << "results in " << out_dir << "\n";
  return all_ok ? kOk : kNumerical;
}

}  // namespace refdyn::app
