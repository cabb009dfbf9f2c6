#include "refdyn/io/results.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/common/version.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <mutex>
#include <thread>

namespace refdyn::io {

namespace fs = std::filesystem;

bool Results::ok() const {
  if (!plan.summary.ok()) return false;
  for (const auto& r : runs)
    if (!r.summary.ok()) return false;
  return true;
}

void for_each_index(size_t count, int shard, int num_shards, int jobs, const std::function<void(size_t)>& body,
                    const std::function<void(size_t done, size_t total, size_t index)>& after) {
  if (num_shards < 1 || shard < 0 || shard >= num_shards)
    throw Error("shard " + std::to_string(shard) + " of " + std::to_string(num_shards) + " shards");
  std::vector<size_t> mine;
  for (size_t i = 0; i < count; ++i)
    if (static_cast<int>(i % static_cast<size_t>(num_shards)) == shard) mine.push_back(i);
  if (mine.empty()) return;
  if (jobs <= 0) jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  jobs = static_cast<int>(std::min<size_t>(static_cast<size_t>(jobs), mine.size()));
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex after_mutex;
  size_t done = 0;
  std::vector<std::exception_ptr> errors(mine.size());
  auto work = [&] {
    while (!stop) {
      const size_t k = next++;
      if (k >= mine.size()) break;
      try {
        body(mine[k]);
        if (after) {
          std::lock_guard<std::mutex> lock(after_mutex);
          after(++done, mine.size(), mine[k]);
        }
      } catch (...) {
        errors[k] = std::current_exception();
        stop = true;
      }
    }
  };
  if (jobs == 1) {
    work();
  } else {
    std::vector<std::thread> pool;
    pool.reserve(static_cast<size_t>(jobs));
    for (int j = 0; j < jobs; ++j) pool.emplace_back(work);
    for (auto& t : pool) t.join();
  }
  for (const auto& e : errors)  // the first failure in index order, whatever the threads did
    if (e) std::rethrow_exception(e);
}

namespace {

/// Runs the experiments of this shard. Each run gets its own planner (an automatic partition is
/// state that a shared one would carry from run to run) and its own controller, so a run's
/// numbers depend on its experiment only.
void run_experiments(const Problem& p, Results& res, const RunOptions& o) {
  const bool one_run = p.experiments.size() == 1;
  auto run = [&](size_t i) {
    const Experiment& ex = *p.experiments[i];
    RunRecord& rec = res.runs[i];
    const auto planner = p.make_planner();
    std::function<void(double)> progress;
    if (one_run && o.progress) progress = o.progress("experiment " + ex.name, p.integrator.t0, res.plan.summary.t_end);
    ClosedLoopResult r = track_experiment(p, ex, res.plan, *planner, progress);
    rec.summary = summarize_run(p, r);
    if (!o.run_csv_dir.empty()) write_csv_atomic(o.run_csv_dir / ("track_" + ex.name + ".csv"), trajectory_table(r));
    if (i < o.keep_trajectories) rec.result = std::move(r);
    rec.done = true;
  };
  std::function<void(size_t, size_t, size_t)> after;
  if (o.on_run_done)
    after = [&](size_t done, size_t total, size_t i) { o.on_run_done(done, total, p.experiments[i]->name); };
  for_each_index(p.experiments.size(), o.shard, o.num_shards, o.jobs, run, after);
}

}  // namespace

Results run_problem(const Problem& p, const RunOptions& o) {
  if (o.num_shards < 1 || o.shard < 0 || o.shard >= o.num_shards)  // before the plan
    throw Error("run_problem: shard " + std::to_string(o.shard) + " of " + std::to_string(o.num_shards) + " shards");
  const auto start = std::chrono::steady_clock::now();
  Results res;
  res.planner = p.make_planner();
  res.plan = plan_problem(p, *res.planner, o.progress ? o.progress("planning", p.integrator.t0, p.integrator.t1)
                                                 : std::function<void(double)>());
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
  if (o.track && res.plan.summary.t_end > p.integrator.t0) {
    res.runs.resize(p.experiments.size());
    for (size_t i = 0; i < p.experiments.size(); ++i) res.runs[i].experiment = p.experiments[i].get();
    run_experiments(p, res, o);
    res.runs_written = !o.run_csv_dir.empty();
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

RunSummary summarize_run(const Problem& p, const ClosedLoopResult& r) {
  RunSummary s;
  s.status = r.summary.status;
  s.message = r.summary.message;
  s.t_end = r.summary.t_end;
  s.steps = r.summary.steps;
  s.saturated_samples = r.saturated_samples;
  s.wall_time = r.summary.wall_time;
  const int n = r.nq();
  if (!r.t.empty()) s.final_max_abs_error = (r.x.back().head(n) - r.q_ref.back()).cwiseAbs().maxCoeff();
  s.joints = tracking_metrics(r, 1e-3, 0.5 * (p.integrator.t0 + p.integrator.t1));
  for (const auto& m : s.joints) s.peak_abs_tau = std::max(s.peak_abs_tau, m.peak_tau);
  return s;
}

Distribution distribution_of(std::vector<double> v) {
  Distribution d;
  const auto finite_end = std::partition(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
  d.missing = static_cast<long>(v.end() - finite_end);
  v.erase(finite_end, v.end());
  d.count = static_cast<long>(v.size());
  if (v.empty()) {
    d.min = d.p5 = d.p25 = d.p50 = d.p75 = d.p95 = d.p99 = d.max = d.mean = std::nan("");
    return d;
  }
  std::sort(v.begin(), v.end());
  auto at = [&](double f) {  // linear between order statistics (numpy's default, "type 7")
    const double h = f * static_cast<double>(v.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(h));
    const size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (h - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  d.min = v.front();
  d.max = v.back();
  d.p5 = at(0.05), d.p25 = at(0.25), d.p50 = at(0.5), d.p75 = at(0.75), d.p95 = at(0.95), d.p99 = at(0.99);
  double sum = 0;  // in sorted order: the same bits whatever order the runs ended in
  for (double x : v) sum += x;
  d.mean = sum / static_cast<double>(v.size());
  return d;
}

namespace {
JsonValue number_or_null(double x) { return std::isfinite(x) ? JsonValue(x) : JsonValue(); }
}  // namespace

JsonValue distribution_json(const Distribution& d) {
  JsonValue o = JsonValue::object();
  o["count"] = d.count;
  o["missing"] = d.missing;
  for (const auto& [k, x] : {std::pair<const char*, double>{"min", d.min}, {"p5", d.p5}, {"p25", d.p25}, {"p50", d.p50},
                             {"p75", d.p75}, {"p95", d.p95}, {"p99", d.p99}, {"max", d.max}, {"mean", d.mean}})
    o[k] = number_or_null(x);
  return o;
}

namespace {

/// The largest finite value (NaN when none): a run's settle time is that of its slowest joint.
double max_finite(const std::vector<JointTracking>& js, double JointTracking::*field) {
  double m = std::nan("");
  for (const auto& j : js)
    if (std::isfinite(j.*field) && !(m >= j.*field)) m = j.*field;
  return m;
}

/// A CSV text field (RFC 4180): quoted when it holds a comma, a quote or a line break.
std::string csv_text(const std::string& x) {
  if (x.find_first_of(",\"\r\n") == std::string::npos) return x;
  std::string q = "\"";
  for (char ch : x) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

/// The sweep parameters over all runs, in order of first appearance.
std::vector<std::string> sweep_names(const Results& res) {
  std::vector<std::string> names;
  for (const RunRecord& r : res.runs)
    for (const auto& kv : r.experiment->sweep)
      if (std::find(names.begin(), names.end(), kv.first) == names.end()) names.push_back(kv.first);
  return names;
}

}  // namespace

std::string sweep_csv(const Problem& p, const Results& res) {
  const std::vector<std::string> params = sweep_names(res);
  const std::vector<std::string>& joints = p.model.joint_name;
  bool sampled = false;  // a `sample` column when some run is a Monte Carlo sample
  for (const RunRecord& r : res.runs) sampled = sampled || r.experiment->sample >= 0;
  std::string s = "index,name,status";
  if (sampled) s += ",sample";
  for (const auto& k : params) s += "," + k;
  s += ",t_end,final_max_abs_error,peak_abs_tau,max_e0,max_settle_time,max_late_error,saturated_samples";
  for (const char* f : {"e0_", "settle_", "late_", "peak_tau_"})
    for (const auto& j : joints) s += "," + std::string(f) + j;
  s += ",message\n";
  auto num = [](double x) { return std::isfinite(x) ? fmt(x) : std::string("nan"); };
  for (size_t i = 0; i < res.runs.size(); ++i) {
    const RunRecord& r = res.runs[i];
    const RunSummary& m = r.summary;
    s += std::to_string(i) + "," + r.experiment->name + "," + (r.done ? to_string(m.status) : "not_run");
    if (sampled) s += "," + (r.experiment->sample >= 0 ? std::to_string(r.experiment->sample) : std::string());
    for (const auto& k : params) {
      s += ",";
      for (const auto& [name, v] : r.experiment->sweep)
        if (name == k) s += num(v);
    }
    s += "," + num(m.t_end) + "," + num(m.final_max_abs_error) + "," + num(m.peak_abs_tau) + "," +
         num(max_finite(m.joints, &JointTracking::e0)) + "," + num(max_finite(m.joints, &JointTracking::settle_time)) +
         "," + num(max_finite(m.joints, &JointTracking::late_error)) + "," + std::to_string(m.saturated_samples);
    for (double JointTracking::*f : {&JointTracking::e0, &JointTracking::settle_time, &JointTracking::late_error,
                                     &JointTracking::peak_tau})
      for (size_t j = 0; j < joints.size(); ++j) s += "," + (j < m.joints.size() ? num(m.joints[j].*f) : std::string("nan"));
    s += "," + csv_text(m.message) + "\n";
  }
  return s;
}

JsonValue summary_json(const Problem& p, const Results& res) {
  JsonValue s = JsonValue::object();
  s["refdyn_version"] = version();
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
  plan["residual_tolerance"] = number_or_null(p.residual_tolerance);
  if (p.residual_from > p.integrator.t0)
    plan["max_constraint_residual_after_" + fmt(p.residual_from) + "s"] = ps.max_constraint_residual;
  plan["wall_time_s"] = ps.wall_time;
  s["feasibility"] = res.feasibility.to_json();
  if (res.runs.empty()) return s;
  const double late = 0.5 * (p.integrator.t0 + p.integrator.t1);
  const std::string late_key = "max_abs_error_after_" + fmt(late) + "s";
  JsonValue& runs = s["runs"] = JsonValue::array();
  for (const RunRecord& rr : res.runs) {
    const RunSummary& r = rr.summary;
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
    o["status"] = rr.done ? to_string(r.status) : "not_run";
    o["message"] = r.message;
    o["t_end"] = r.t_end;
    o["saturated_samples"] = r.saturated_samples;
    o["final_max_abs_error"] = r.final_max_abs_error;
    o["peak_abs_tau"] = r.peak_abs_tau;
    JsonValue& js = o["joints"] = JsonValue::array();
    for (size_t j = 0; j < r.joints.size(); ++j) {
      JsonValue& e = js.push_back(JsonValue::object());
      e["joint"] = p.model.joint_name[j];
      e["e0"] = r.joints[j].e0;
      e["settle_time_rel_1e-3"] = r.joints[j].settle_time;
      e[late_key] = r.joints[j].late_error;
      e["peak_abs_tau"] = r.joints[j].peak_tau;
    }
    o["wall_time_s"] = r.wall_time;
  }
  // Statistics over the runs (the aggregate of a sweep or Monte Carlo study).
  JsonValue& st = s["statistics"] = JsonValue::object();
  long ok = 0;
  std::vector<double> fin, peak, e0, settle, lateE;
  for (const RunRecord& rr : res.runs) {
    const RunSummary& r = rr.summary;
    ok += rr.done && r.ok();
    fin.push_back(r.final_max_abs_error);
    peak.push_back(r.peak_abs_tau);
    e0.push_back(max_finite(r.joints, &JointTracking::e0));
    settle.push_back(max_finite(r.joints, &JointTracking::settle_time));
    lateE.push_back(max_finite(r.joints, &JointTracking::late_error));
  }
  st["runs"] = static_cast<long>(res.runs.size());
  st["completed"] = ok;
  st["stopped_early"] = static_cast<long>(res.runs.size()) - ok;
  st["percentiles"] = "linear between order statistics (numpy default); NaN values counted as missing";
  st["final_max_abs_error"] = distribution_json(distribution_of(fin));
  st["peak_abs_tau"] = distribution_json(distribution_of(peak));
  st["max_e0"] = distribution_json(distribution_of(e0));
  st["max_settle_time_rel_1e-3"] = distribution_json(distribution_of(settle));
  st["max_" + late_key] = distribution_json(distribution_of(lateE));
  JsonValue& sj = st["joints"] = JsonValue::array();
  for (int j = 0; j < p.model.nv; ++j) {
    JsonValue& o = sj.push_back(JsonValue::object());
    o["joint"] = p.model.joint_name[j];
    for (const auto& [key, f] : {std::pair<std::string, double JointTracking::*>{"e0", &JointTracking::e0},
                                 {"settle_time_rel_1e-3", &JointTracking::settle_time},
                                 {late_key, &JointTracking::late_error},
                                 {"peak_abs_tau", &JointTracking::peak_tau}}) {
      std::vector<double> v;
      for (const RunRecord& rr : res.runs)
        v.push_back(static_cast<size_t>(j) < rr.summary.joints.size() ? rr.summary.joints[j].*f : std::nan(""));
      o[key] = distribution_json(distribution_of(std::move(v)));
    }
  }
  return s;
}

void write_results(const fs::path& dir, const Problem& p, const Results& res, const JsonValue& summary) {
  prepare_output_dir(dir);
  write_csv_atomic(dir / "plan.csv", trajectory_table(res.plan));
  for (const RunRecord& r : res.runs)
    if (!res.runs_written && r.done && !r.result.joints.empty())
      write_csv_atomic(dir / ("track_" + r.experiment->name + ".csv"), trajectory_table(r.result));
  write_text_atomic(dir / "feasibility.json", res.feasibility.to_json().dump(0) + "\n");
  if (!res.runs.empty()) write_text_atomic(dir / "sweep.csv", sweep_csv(p, res));
  write_text_atomic(dir / "summary.json", summary.dump(2, 2) + "\n");
}

}  // namespace refdyn::io
