// refdyn check / plan / track / generate / kinds: thin clients of the library's pipeline
// (io::load_problem → io::run_problem → io::write_results).
#include "commands.hpp"
#include "report.hpp"

#include "refdyn/error.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/symbolic.hpp"
#include "refdyn/registry.hpp"
#include "refdyn/text.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <unistd.h>

namespace refdyn::app {

namespace fs = std::filesystem;

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
  s += c.order() == 3 ? ", jerk-level" : c.order() == 2 ? ", acceleration-level" : c.first_order() ? ", first-order" : ", holonomic";
  s += c.rheonomic() ? ", rheonomic" : ", scleronomic";
  return s;
}

void print_plan(const Problem& p, const Plan& plan) {
  std::printf("scenario '%s': %d DOF, %d constraint rows; plan %s, %ld steps, t_end = %.6g s, max |Phi| = %.3g, %.3f s\n",
              p.name.c_str(), p.model.nq, p.constraints.rows(), to_string(plan.summary.status), plan.summary.steps,
              plan.summary.t_end, plan.summary.max_constraint_residual, plan.summary.wall_time);
  if (!plan.summary.ok()) std::printf("  stopped: %s\n", plan.summary.message.c_str());
}

}  // namespace

/// The one-line report of a run that stopped early (printed even with -q).
void report_stopped(const io::Results& r) {
  if (!r.plan.summary.ok())
    std::fprintf(stderr, "refdyn: error: the plan stopped early: %s\n", r.plan.summary.message.c_str());
  for (const auto& run : r.runs)
    if (!run.result.summary.ok())
      std::fprintf(stderr, "refdyn: error: experiment '%s' stopped early: %s\n", run.experiment->name.c_str(),
                   run.result.summary.message.c_str());
}

io::ProgressFactory terminal_progress(bool enabled) {
  if (!enabled) return {};
  return [](const std::string& what, double t0, double t1) -> std::function<void(double)> {
    auto bar = std::make_shared<Progress>(what, t0, t1);
    return [bar](double t) { bar->update(t); };
  };
}

int run_check(const std::string& file, const InputOptions& in) {
  const auto sp = io::load_problem(file, in.max_input_bytes);
  const Problem& s = *sp;
  const Model& m = s.model;
  if (s.is_jerk_problem()) {  // planned by JerkDynamics: state [q; q̇; q̈], no partition
    JerkDynamics jd(m, s.jerk_constraints, JerkDynamicsOptions{s.kappa}, &s.forces);
    const Eigen::VectorXd x = jd.initial_state(s.integrator.t0, s.q0, s.qd0, s.qdd0.size() ? &s.qdd0 : nullptr);
    Eigen::VectorXd dx(x.size());
    jd.derivative(s.integrator.t0, x, dx);
    std::cout << "scenario '" << s.name << "' (" << file << "): valid\n" << m.summary();
    std::cout << "constraints: " << s.constraints.size() << " (" << s.constraints.rows() << " rows)\n";
    for (const auto& c : s.constraints.constraints())
      std::cout << "  " << c->name << ": " << constraint_kind(*c) << ": " << c->describe() << "\n";
    std::cout << "jerk-level problem (p = 3): state [q; qd; qdd], kappa = " << s.kappa << " 1/s\n";
    std::cout << "initial acceleration at t0 = " << s.integrator.t0 << " s" << (s.qdd0.size() ? " (from initial.qdd)" : " (free)")
              << ":";
    for (int j = 0; j < m.nq; ++j) std::cout << " " << m.joint_name[j] << " " << x[2 * m.nq + j];
    std::cout << "\n";
    for (int r = 0; r < s.constraints.rows(); ++r)
      std::printf("  %-20s |B qddd + s| = %.3e\n", s.constraints.row_name(r).c_str(), std::abs(jd.row_residual()[r]));
    std::cout << "integrator: " << to_string(s.integrator.method) << ", step " << s.integrator.step << " s, t = ["
              << s.integrator.t0 << ", " << s.integrator.t1 << "] s\n";
    return kOk;
  }
  // Everything is evaluated before anything is printed: "valid" is never followed by an error.
  ReferenceDynamics rd(m, s.forces, s.constraints, s.options);
  Eigen::VectorXd x = rd.make_state(s.q0, s.qd0), dx(x.size());
  rd.derivative(s.integrator.t0, x, dx);
  std::cout << "scenario '" << s.name << "' (" << file << "): valid\n" << m.summary();
  std::cout << "constraints: " << s.constraints.size() << " (" << s.constraints.rows() << " rows)\n";
  int mat = 0, prog = 0, hol = 0, fo = 0, acc = 0;
  for (const auto& c : s.constraints.constraints()) {
    std::cout << "  " << c->name << ": " << constraint_kind(*c) << ": " << c->describe() << "\n";
    (c->origin == ConstraintOrigin::Material ? mat : prog) += c->rows();
    (c->order() == 2 ? acc : c->first_order() ? fo : hol) += c->rows();  // (order 3: jerk problems, above)
  }
  std::cout << "  rows by kind: " << mat << " material, " << prog << " programmed; " << hol << " holonomic, " << fo
            << " first-order" << (acc ? ", " + std::to_string(acc) + " acceleration-level" : std::string()) << "\n";
  std::cout << "force elements: " << s.forces.elements().size();
  for (const auto& e : s.forces.elements()) std::cout << "  " << e->name();
  std::cout << "\n";
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

namespace {
int plan_or_track(const std::string& file, const std::string& out_dir, bool quiet, bool track, const InputOptions& in,
                  bool report) {
  const auto problem = io::load_problem(file, in.max_input_bytes);  // validates before anything is written
  if (track && problem->experiments.empty())
    throw Error(file + ": experiments: missing (track needs at least one experiment; see docs/scenario.md)");
  io::RunOptions o;
  o.track = track;
  o.progress = terminal_progress(!quiet);
  const io::Results r = io::run_problem(*problem, o);
  const JsonValue summary = io::summary_json(*problem, r);
  io::write_results(out_dir, *problem, r, summary);
  if (report) write_report(out_dir, *problem, r, summary);
  if (!quiet) {
    print_plan(*problem, r.plan);
    for (const auto& run : r.runs) {
      const auto& res = run.result;
      const int n = res.nq();
      const double last_e = res.t.empty() ? 0.0 : (res.x.back().head(n) - res.q_ref.back()).cwiseAbs().maxCoeff();
      double peak = 0;
      for (const auto& tau : res.tau) peak = std::max(peak, tau.cwiseAbs().maxCoeff());
      std::printf("  %-24s %s, final max |e| = %.3g, peak |tau| = %.4g%s\n", run.experiment->name.c_str(),
                  to_string(res.summary.status), last_e, peak,
                  res.summary.ok() ? "" : (" (" + res.summary.message + ")").c_str());
    }
    std::cout << r.feasibility.text() << "results in " << out_dir << (report ? " (report.html)" : "") << "\n";
  }
  if (!r.ok()) {
    report_stopped(r);
    return kNumerical;
  }
  return kOk;
}
}  // namespace

int run_plan(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in, bool report) {
  return plan_or_track(file, out_dir, quiet, false, in, report);
}

int run_track(const std::string& file, const std::string& out_dir, bool quiet, const InputOptions& in, bool report) {
  return plan_or_track(file, out_dir, quiet, true, in, report);
}

int run_generate(const std::string& file, const std::string& out_dir, const std::string& formats,
                 const std::string& prefix, bool quiet, const InputOptions& in) {
  bool c = false, latex = false, json = false;
  std::string rest = formats;
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    const std::string f = rest.substr(0, comma);
    rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
    if (f == "c") c = true;
    else if (f == "latex") latex = true;
    else if (f == "json") json = true;
    else throw Error("--format: expected a comma-separated list of c, latex, json, got '" + f + "'");
  }
  if (!c && !latex && !json) throw Error("--format: expected at least one of c, latex, json");
  const auto problem = io::load_problem(file, in.max_input_bytes);
  SymbolicOptions opt;
  opt.prefix = prefix;
  const SymbolicReferenceDynamics g = generate_symbolic(*problem, opt);
  // Everything is formed before the first file is written: an error leaves the folder as it was.
  std::vector<std::pair<std::string, std::string>> files;
  if (c) {
    files.emplace_back("reference_dynamics.h", g.c_header());
    files.emplace_back("reference_dynamics.c", g.c_source());
  }
  if (latex) files.emplace_back("equations.tex", g.latex());
  if (json) files.emplace_back("reference_dynamics.json", g.json());
  io::prepare_output_dir(out_dir);
  for (const auto& [name, text] : files) io::write_text_atomic(std::filesystem::path(out_dir) / name, text);
  if (!quiet) {
    const SymbolicSummary& s = g.summary();
    std::printf("generated the reference dynamics of '%s': %d coordinates, %d constraint rows, %d force states, "
                "%d parameters in %.2f s\n",
                problem->name.c_str(), s.nq, s.constraints, s.nz, s.parameters, s.seconds);
    if (c) std::printf("C: prefix %s, %ld common subexpressions, %ld operations\n", g.prefix().c_str(), s.c_temporaries, s.c_operations);
    for (const auto& f : files) std::printf("  %s\n", (std::filesystem::path(out_dir) / f.first).c_str());
  }
  return kOk;
}

int run_kinds() {
  std::cout << registry_markdown();
  return kOk;
}

}  // namespace refdyn::app
