#include "refdyn/io/results.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/fields_json.hpp"
#include "refdyn/io/csv.hpp"
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

std::optional<PlannerPartition> partition_at_t0(const Problem& p) {
  if (p.is_jerk_problem()) return std::nullopt;
  try {
    ReferenceDynamicsOptions o = p.options;
    o.solver = ReferenceSolver::Projection;  // the same partition and κ as a projection plan's, bit for bit
    ReferenceDynamics rd(p.model, p.forces, p.constraints, o);
    ReferencePlanner planner(rd);
    const Eigen::VectorXd x = p.initial_state(planner);
    Eigen::VectorXd dx(x.size());
    planner.derivative(p.integrator.t0, x, dx);
    return planner.partition();
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

ReferenceSolver resolved_solver(const Problem& p) {
  return p.options.solver == ReferenceSolver::Automatic
             ? automatic_reference_solver(p.model.nq, p.constraints.rows())
             : p.options.solver;
}

Results run_problem(const Problem& p, const RunOptions& o) {
  if (o.num_shards < 1 || o.shard < 0 || o.shard >= o.num_shards)  // before the plan
    throw Error("run_problem: shard " + std::to_string(o.shard) + " of " + std::to_string(o.num_shards) + " shards");
  const auto start = std::chrono::steady_clock::now();
  Results res;
  res.planner = p.make_planner();
  res.partition_t0 = partition_at_t0(p);
  res.plan = plan_problem(p, *res.planner, o.progress ? o.progress("planning", p.integrator.t0, p.integrator.t1)
                                                 : std::function<void(double)>());
  const int n = p.model.nv;
  SampleSeries q, qd;
  q.reserve(res.plan.x.size()), qd.reserve(res.plan.x.size());
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
  s.max_material_residual = r.max_material_residual;
  s.initial_correction_q = r.initial_correction_q;
  s.initial_correction_qd = r.initial_correction_qd;
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

double RunSummary::max_over_joints(double JointTracking::*field) const {
  double m = std::nan("");
  for (const auto& j : joints)
    if (std::isfinite(j.*field) && !(m >= j.*field)) m = j.*field;
  return m;
}

namespace {

/// The sweep parameters over all runs, in order of first appearance.
std::vector<std::string> sweep_names(const Results& res) {
  std::vector<std::string> names;
  for (const RunRecord& r : res.runs)
    for (const auto& kv : r.experiment->sweep)
      if (std::find(names.begin(), names.end(), kv.first) == names.end()) names.push_back(kv.first);
  return names;
}

/// What the run fields need beyond a RunSummary: the joint names and the start of the "late"
/// window (the middle of the integration span) in the late-error key.
FieldContext run_context(const Problem& p) {
  FieldContext c;
  c.names = &p.model.joint_name;
  c.late = fmt(0.5 * (p.integrator.t0 + p.integrator.t1));
  return c;
}

}  // namespace

std::string sweep_csv(const Problem& p, const Results& res) {
  const std::vector<std::string> params = sweep_names(res);
  const FieldContext c = run_context(p);
  bool sampled = false;  // a `sample` column when some run is a Monte Carlo sample
  for (const RunRecord& r : res.runs) sampled = sampled || r.experiment->sample >= 0;
  std::vector<std::string> head = {"index", "name", "status"};
  if (sampled) head.push_back("sample");
  head.insert(head.end(), params.begin(), params.end());
  csv_columns<RunSummary>(head, c);
  const bool plant_rows = p.material != nullptr;  // the material rows' columns
  if (plant_rows) head.insert(head.end(), {"max_material_residual", "initial_correction_q", "initial_correction_qd"});
  std::string s = csv_line(head);
  for (size_t i = 0; i < res.runs.size(); ++i) {
    const RunRecord& r = res.runs[i];
    std::vector<std::string> cells = {std::to_string(i), r.experiment->name,
                                      r.done ? to_string(r.summary.status) : "not_run"};
    if (sampled) cells.push_back(r.experiment->sample >= 0 ? std::to_string(r.experiment->sample) : std::string());
    for (const auto& k : params) {
      std::string cell;
      for (const auto& [name, v] : r.experiment->sweep)
        if (name == k) cell += csv_number(v);
      cells.push_back(cell);
    }
    csv_cells(cells, r.summary, c);
    if (plant_rows)
      for (double v : {r.summary.max_material_residual, r.summary.initial_correction_q, r.summary.initial_correction_qd})
        cells.push_back(csv_number(v));
    s += csv_line(cells);
  }
  return s;
}

static JsonValue partition_json(const Model& m, const std::optional<PlannerPartition>& part, bool automatic,
                                bool used) {
  if (!part) return JsonValue();  // a jerk problem: no partition
  auto names = [&](const std::vector<int>& idx) {
    JsonValue a = JsonValue::array();
    for (int i : idx) a.push_back(m.joint_name[i]);
    return a;
  };
  JsonValue o = JsonValue::object();
  o["independent"] = names(part->independent);
  o["dependent"] = names(part->dependent);
  o["automatic"] = automatic;
  o["condition"] = number_or_null(part->condition);
  o["used_by_solver"] = used;  // false: the Lagrange solver; the partition is the projection solver's
  return o;
}

JsonValue summary_json(const Problem& p, const Results& res) {
  JsonValue s = JsonValue::object();
  s["refdyn_version"] = version();
  s["scenario"] = p.name;
  s["file"] = p.file;
  s["wall_time_s"] = res.wall_time;
  JsonValue& plan = s["plan"] = to_json(res.plan.summary);
  const JsonValue wall = plan["wall_time_s"];  // the plan's context, then its wall time last
  plan.erase("wall_time_s");
  plan["residual_from"] = p.residual_from;
  plan["residual_tolerance"] = number_or_null(p.residual_tolerance);
  if (p.residual_from > p.integrator.t0)
    plan["max_constraint_residual_after_" + fmt(p.residual_from) + "s"] = res.plan.summary.max_constraint_residual;
  plan["partition_t0"] = partition_json(p.model, res.partition_t0, p.automatic_independent, solver_uses_partition(p));
  plan["wall_time_s"] = wall;
  s["feasibility"] = res.feasibility.to_json();
  if (res.runs.empty()) return s;
  const FieldContext c = run_context(p);
  JsonValue& runs = s["runs"] = JsonValue::array();
  for (const RunRecord& rr : res.runs) {
    JsonValue o = JsonValue::object();
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
    write_fields_json(o, rr.summary, c);
    if (!rr.done) o["status"] = "not_run";
    runs.push_back(std::move(o));
  }
  // Statistics over the runs (the aggregate of a sweep or Monte Carlo study): a distribution of
  // every field marked sink::Stat, overall and per joint.
  JsonValue& st = s["statistics"] = JsonValue::object();
  long ok = 0;
  for (const RunRecord& rr : res.runs) ok += rr.done && rr.summary.ok();
  st["runs"] = static_cast<long>(res.runs.size());
  st["completed"] = ok;
  st["stopped_early"] = static_cast<long>(res.runs.size()) - ok;
  st["percentiles"] = "linear between order statistics (numpy default); NaN values counted as missing";
  for_each_field<RunSummary>([&](const auto& f) {
    if constexpr (std::is_same_v<typename std::decay_t<decltype(f)>::Value, double>) {
      if (!(f.in & sink::Stat)) return;
      std::vector<double> v;
      for (const RunRecord& rr : res.runs) v.push_back(f.get(rr.summary));
      st[c.expand(f.key())] = distribution_json(distribution_of(std::move(v)));
    }
  });
  JsonValue& sj = st["joints"] = JsonValue::array();
  for (size_t j = 0; j < static_cast<size_t>(p.model.nv); ++j) {
    JsonValue o = JsonValue::object();
    o["joint"] = p.model.joint_name[j];
    for_each_field<JointTracking>([&](const auto& f) {
      if (!(f.in & sink::Stat)) return;
      std::vector<double> v;
      for (const RunRecord& rr : res.runs)
        v.push_back(j < rr.summary.joints.size() ? f.get(rr.summary.joints[j]) : std::nan(""));
      o[c.expand(f.key())] = distribution_json(distribution_of(std::move(v)));
    });
    sj.push_back(std::move(o));
  }
  return s;
}

void write_results(const fs::path& dir, const Problem& p, const Results& res, const JsonValue& summary) {
  prepare_output_dir(dir);
  write_csv_atomic(dir / "plan.csv", trajectory_table(res.plan));
  for (const RunRecord& r : res.runs)
    if (!res.runs_written && r.done && !r.result.joints.empty())
      write_csv_atomic(dir / ("track_" + r.experiment->name + ".csv"), trajectory_table(r.result));
  write_text_atomic(dir / "feasibility.json", res.feasibility.json() + "\n");
  if (!res.runs.empty()) write_text_atomic(dir / "sweep.csv", sweep_csv(p, res));
  write_text_atomic(dir / "summary.json", json_text(summary, 2, 2) + "\n");
}

}  // namespace refdyn::io
