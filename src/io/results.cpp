#include "refdyn/io/results.hpp"

#include "refdyn/error.hpp"
#include "refdyn/text.hpp"

#include <chrono>
#include <cmath>

namespace refdyn::io {

namespace fs = std::filesystem;

bool Results::ok() const {
  if (!plan.summary.ok()) return false;
  for (const auto& r : runs)
    if (!r.result.summary.ok()) return false;
  return true;
}

Results run_problem(const Problem& p, const RunOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  Results res;
  res.rd = p.make_reference_dynamics();
  auto progress = [&](const std::string& what, double t0, double t1) {
    return o.progress ? o.progress(what, t0, t1) : std::function<void(double)>();
  };
  res.plan = plan_problem(p, *res.rd, progress("planning", p.integrator.t0, p.integrator.t1));
  const int n = p.model.nv;
  std::vector<Eigen::VectorXd> q, qd;
  for (const auto& x : res.plan.x) q.push_back(x.head(n)), qd.push_back(x.segment(n, n));
  res.feasibility = assess_feasibility(p.model, res.plan.t, q, qd, res.plan.qdd, res.plan.actuator_effort);
  if (!res.plan.summary.ok()) {
    res.feasibility.complete = false;
    res.feasibility.incomplete_reason = res.plan.summary.message;
  }
  // Experiments track the plan up to where it ended; a plan that stopped at t0 leaves nothing
  // to track (the stopped plan is reported).
  if (o.track && res.plan.summary.t_end > p.integrator.t0)
    for (const auto& ex : p.experiments) {
      RunRecord r;
      r.experiment = ex.get();
      r.result = track_experiment(p, *ex, res.plan, *res.rd,
                                  progress("experiment " + ex->name, p.integrator.t0, res.plan.summary.t_end));
      res.runs.push_back(std::move(r));
    }
  res.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return res;
}

CsvTable trajectory_table(const Trajectory& tr) {
  const size_t K = tr.size();
  const int n = tr.nq();
  CsvTable t;
  auto cols = [&](const char* prefix, const std::vector<std::string>& names) {
    for (const auto& nm : names) t.header.push_back(prefix + nm);
  };
  const bool plan = !tr.qdd.empty();
  const bool loop = !tr.tau.empty();
  t.header = {"t"};
  cols("q_", tr.joints);
  cols("qd_", tr.joints);
  if (plan) cols("qdd_", tr.joints);
  if (loop) {
    cols("qref_", tr.joints);
    cols("e_", tr.joints);
    cols("tau_", tr.joints);
  }
  if (plan) cols("", tr.state_names);
  for (const auto& p : tr.points)
    for (const char* a : {"_x", "_y", "_z"}) t.header.push_back(p + a);
  const bool targets = !tr.targets.empty() && !tr.target_signals.empty();
  if (targets) cols("", tr.target_signals);
  const bool rows = !tr.phi.empty();
  if (rows) {
    cols("phi_", tr.constraint_rows);
    cols("phid_", tr.constraint_rows);
  }
  const bool signals = !tr.forces.empty() && !tr.force_signals.empty();
  if (signals) cols("", tr.force_signals);
  if (!tr.Qc.empty()) cols("Qc_", tr.joints);
  if (!tr.actuator_effort.empty()) cols("required_", tr.joints);
  if (!tr.reaction_effort.empty()) cols("reaction_", tr.joints);
  if (rows) cols("lambda_", tr.constraint_rows);
  const size_t nstates = tr.state_names.size();
  t.rows.reserve(K);
  for (size_t k = 0; k < K; ++k) {
    std::vector<double> row;
    row.reserve(t.header.size());
    auto put = [&row](const Eigen::VectorXd& v) { row.insert(row.end(), v.data(), v.data() + v.size()); };
    row.push_back(tr.t[k]);
    for (int i = 0; i < 2 * n; ++i) row.push_back(tr.x[k][i]);
    if (plan) put(tr.qdd[k]);
    if (loop) {
      put(tr.q_ref[k]);
      for (int j = 0; j < n; ++j) row.push_back(tr.x[k][j] - tr.q_ref[k][j]);
      put(tr.tau[k]);
    }
    if (plan)
      for (size_t i = 0; i < nstates; ++i) row.push_back(tr.x[k][2 * n + i]);
    if (!tr.points.empty()) put(tr.point_positions[k]);
    if (targets) put(tr.targets[k]);
    if (rows) {
      put(tr.phi[k]);
      put(tr.phid[k]);
    }
    if (signals) put(tr.forces[k]);
    if (!tr.Qc.empty()) put(tr.Qc[k]);
    if (!tr.actuator_effort.empty()) put(tr.actuator_effort[k]);
    if (!tr.reaction_effort.empty()) put(tr.reaction_effort[k]);
    if (rows) put(tr.lambda[k]);
    t.add_row(std::move(row));
  }
  return t;
}

std::vector<JointTracking> tracking_metrics(const ClosedLoopResult& r, double frac, double late_from) {
  const int n = r.nq();
  std::vector<JointTracking> out(n);
  if (r.t.empty()) return out;
  for (int j = 0; j < n; ++j) {
    JointTracking& m = out[j];
    m.e0 = std::abs(r.x[0][j] - r.q_ref[0][j]);
    m.settle_time = std::nan("");
    if (m.e0 != 0)
      for (size_t k = r.t.size(); k-- > 0;) {
        if (std::abs(r.x[k][j] - r.q_ref[k][j]) >= frac * m.e0) break;
        m.settle_time = r.t[k];
      }
    for (size_t k = 0; k < r.t.size(); ++k) {
      m.peak_tau = std::max(m.peak_tau, std::abs(r.tau[k][j]));
      if (r.t[k] >= late_from) m.late_error = std::max(m.late_error, std::abs(r.x[k][j] - r.q_ref[k][j]));
    }
  }
  return out;
}

JsonValue summary_json(const Problem& p, const Results& res) {
  JsonValue s = JsonValue::object();
  s["scenario"] = p.name;
  s["file"] = p.file;
  s["wall_time_s"] = res.wall_time;
  const IntegrationSummary& ps = res.plan.summary;
  JsonValue& plan = s["plan"] = JsonValue::object();
  plan["status"] = to_string(ps.status);
  plan["message"] = ps.message;
  plan["steps"] = ps.steps;
  plan["rejected_steps"] = ps.rejected_steps;
  plan["t_end"] = ps.t_end;
  plan["max_constraint_residual"] = ps.max_constraint_residual;
  plan["residual_from"] = p.residual_from;
  if (p.residual_from > p.integrator.t0)
    plan["max_constraint_residual_after_" + fmt(p.residual_from) + "s"] = ps.max_constraint_residual;
  plan["wall_time_s"] = ps.wall_time;
  s["feasibility"] = res.feasibility.to_json();
  if (!res.runs.empty()) {
    const double late = 0.5 * (p.integrator.t0 + p.integrator.t1);
    const std::string late_key = "max_abs_error_after_" + fmt(late) + "s";
    JsonValue& runs = s["runs"] = JsonValue::array();
    for (const RunRecord& rr : res.runs) {
      const ClosedLoopResult& r = rr.result;
      JsonValue& o = runs.push_back(JsonValue::object());
      o["label"] = rr.experiment->name;
      if (!rr.experiment->sweep.empty()) {
        JsonValue& sw = o["sweep"] = JsonValue::object();
        for (const auto& [k, v] : rr.experiment->sweep) sw[k] = v;
      }
      if (rr.experiment->sample >= 0) {
        o["sample"] = rr.experiment->sample;
        o["seed"] = rr.experiment->seed;
      }
      o["controller"] = rr.experiment->controller_type;
      o["plant_force_elements"] = static_cast<int>(rr.experiment->plant_forces.elements().size());
      o["status"] = to_string(r.summary.status);
      o["message"] = r.summary.message;
      o["saturated_samples"] = r.saturated_samples;
      double last_e = 0, peak = 0;
      const int n = r.nq();
      if (!r.t.empty()) last_e = (r.x.back().head(n) - r.q_ref.back()).cwiseAbs().maxCoeff();
      const auto metrics = tracking_metrics(r, 1e-3, late);
      for (const auto& m : metrics) peak = std::max(peak, m.peak_tau);
      o["final_max_abs_error"] = last_e;
      o["peak_abs_tau"] = peak;
      JsonValue& js = o["joints"] = JsonValue::array();
      for (int j = 0; j < n; ++j) {
        JsonValue& e = js.push_back(JsonValue::object());
        e["joint"] = r.joints[j];
        e["e0"] = metrics[j].e0;
        e["settle_time_rel_1e-3"] = metrics[j].settle_time;
        e[late_key] = metrics[j].late_error;
        e["peak_abs_tau"] = metrics[j].peak_tau;
      }
      o["wall_time_s"] = r.summary.wall_time;
    }
  }
  return s;
}

void write_results(const fs::path& dir, const Problem& p, const Results& res, const JsonValue& summary) {
  prepare_output_dir(dir);
  write_csv_atomic(dir / "plan.csv", trajectory_table(res.plan));
  for (const RunRecord& r : res.runs)
    write_csv_atomic(dir / ("track_" + r.experiment->name + ".csv"), trajectory_table(r.result));
  write_text_atomic(dir / "feasibility.json", res.feasibility.to_json().dump(0) + "\n");
  write_text_atomic(dir / "summary.json", summary.dump(2, 2) + "\n");
}

}  // namespace refdyn::io
