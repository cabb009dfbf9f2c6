// plan_motion and plan_jerk_motion (plan.hpp): a reference dynamics integrated and recorded.
#include "refdyn/simulate/plan.hpp"

#include "refdyn/simulate/stability.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <limits>
#include <sstream>

namespace refdyn {

namespace {

/// The reference dynamics of order ≤ 2 as PlanRecorder reads it (state [q; q̇; z]).
struct SecondOrderSource {
  ReferenceDynamics& rd;

  const Model& model() const { return rd.model(); }
  const ForceSet* forces() const { return &rd.forces(); }
  const ConstraintSet& constraint_set() const { return rd.constraint_set(); }
  int num_constraints() const { return rd.num_constraints(); }
  int state_size() const { return rd.state_size(); }
  int z_offset() const { return 2 * rd.nq(); }
  std::vector<std::string> state_names() const { return rd.forces().state_names(); }
  /// Every row is a row of the constraint set.
  void row_names(Plan& plan, bool& any_material) const { set_rows(constraint_set(), plan, any_material); }
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { rd.derivative(t, x, dx); }
  /// q̈ is the dynamics' output: not a number where it failed.
  void qdd(const Eigen::VectorXd&, const Eigen::VectorXd& dx, bool ok, Eigen::VectorXd& out) const {
    const int n = rd.nq();
    if (ok) out = dx.segment(n, n);
    else out.setConstant(n, std::nan(""));
  }
  /// The kinematics of the evaluation (a failed one may not have reached them: done here).
  const Data& kinematics(const Eigen::VectorXd& q, bool ok) {
    if (!ok) forward_kinematics(rd.model(), rd.data(), q);
    return rd.data();
  }
  const Eigen::VectorXd& phi() const { return rd.constraints().phi; }
  const Eigen::VectorXd& phid() const { return rd.constraints().phid; }
  const Eigen::VectorXd& lambda() const { return rd.lambda(); }
  const Eigen::VectorXd& constraint_force() const { return rd.constraint_force(); }
  const Eigen::MatrixXd& row_jacobian() const { return rd.constraints().A; }

  static void set_rows(const ConstraintSet& cs, Plan& plan, bool& any_material) {
    for (int r = 0; r < cs.rows(); ++r) {
      plan.constraint_rows.push_back(cs.row_name(r));
      const bool mat = cs.constraints()[cs.row_owner(r)]->origin == ConstraintOrigin::Material;
      plan.material_row.push_back(mat ? 1 : 0);
      any_material = any_material || mat;
    }
  }
};

/// The jerk dynamics as PlanRecorder reads it (state [q; q̇; q̈; z]; rows: the constraint set's,
/// or the jerk rows alone).
struct JerkSource {
  JerkDynamics& jd;
  Data data{jd.model()};  ///< its own kinematics for the recorded points

  const Model& model() const { return jd.model(); }
  const ForceSet* forces() const { return jd.forces(); }
  const ConstraintSet& constraint_set() const { return jd.constraint_set(); }
  int num_constraints() const { return jd.num_constraints(); }
  int state_size() const { return jd.state_size(); }
  int z_offset() const { return 3 * jd.nq(); }
  std::vector<std::string> state_names() const {
    std::vector<std::string> names;
    for (const std::string& j : jd.model().joint_name) names.push_back("acc_" + j);
    if (jd.forces())
      for (const std::string& z : jd.forces()->state_names()) names.push_back(z);
    return names;
  }
  void row_names(Plan& plan, bool& any_material) const {
    if (constraint_set().rows() == num_constraints()) return SecondOrderSource::set_rows(constraint_set(), plan, any_material);
    for (const auto& c : jd.constraints()) {  // made from jerk rows alone
      plan.constraint_rows.push_back(c->name());
      plan.material_row.push_back(0);
    }
  }
  void derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { jd.derivative(t, x, dx); }
  /// q̈ is part of the state.
  void qdd(const Eigen::VectorXd& x, const Eigen::VectorXd&, bool, Eigen::VectorXd& out) const {
    out = x.segment(2 * jd.nq(), jd.nq());
  }
  const Data& kinematics(const Eigen::VectorXd& q, bool) {
    forward_kinematics(jd.model(), data, q);
    return data;
  }
  const Eigen::VectorXd& phi() const { return jd.row_residual(); }
  const Eigen::VectorXd& phid() const { return jd.row_rate_residual(); }
  const Eigen::VectorXd& lambda() const { return jd.lambda(); }
  const Eigen::VectorXd& constraint_force() const { return jd.constraint_force(); }
  const Eigen::MatrixXd& row_jacobian() const { return jd.B(); }
};

/// Records a reference dynamics' quantities at output samples into a Plan: the one recorder of
/// plan_motion and plan_jerk_motion (Source: SecondOrderSource or JerkSource). evaluate() runs
/// the dynamics at the sample, record() appends what that evaluation gave.
template <class Source>
class PlanRecorder {
 public:
  PlanRecorder(Source source, Plan& plan, const RecordOptions& o)
      : src_(std::move(source)), plan_(plan), n_(src_.model().nq), m_(src_.num_constraints()),
        dx_(src_.state_size()), q_(n_), qd_(n_) {
    const Model& model = src_.model();
    plan.joints = model.joint_name;
    plan.state_names = src_.state_names();
    for (int p : o.points) {
      if (p < 0 || p >= static_cast<int>(model.point_name.size()))
        throw Error(expected_got("recorded point index", "0.." + std::to_string(model.point_name.size()) + " (exclusive)",
                                 std::to_string(p)));
      plan.points.push_back(model.point_name[p]);
    }
    points_ = o.points;
    src_.row_names(plan, any_material_);
    for (const auto& c : src_.constraint_set().constraints())
      if (!c->record_as.empty() && c->target()) {
        plan.target_signals.push_back(c->record_as);
        targets_.push_back(c->target());
      }
    if (const ForceSet* fs = src_.forces())
      for (size_t k = 0; k < fs->elements().size(); ++k) {
        const auto& e = fs->elements()[k];
        const auto names = e->signal_names();
        if (!names.empty()) signal_elements_.push_back(static_cast<int>(k)), signal_counts_.push_back(names.size());
        plan.force_signals.insert(plan.force_signals.end(), names.begin(), names.end());
        if (e->actuator()) actuators_.push_back(static_cast<int>(k));
      }
  }

  Source& source() { return src_; }

  /// Room for the samples an integration over [t0, t1] with these options records (a guess for
  /// adaptive methods; at most 1e7, the series grow past it if need be).
  void reserve(const IntegratorOptions& io) {
    const double every = io.output_interval > 0 ? io.output_interval : io.step;
    const double guess = every > 0 ? (io.t1 - io.t0) / every + 2 : 0;
    const size_t k = std::isfinite(guess) && guess > 0 ? static_cast<size_t>(std::min(guess, 1e7)) : 0;
    plan_.t.reserve(k);
    for (SampleSeries* v : {&plan_.x, &plan_.qdd, &plan_.point_positions, &plan_.targets, &plan_.forces, &plan_.phi,
                            &plan_.phid, &plan_.lambda, &plan_.Qc, &plan_.actuator_effort, &plan_.reaction_effort})
      v->reserve(k);
  }

  /// Evaluates the dynamics at (t, x); false where it failed (NumericalFailure).
  bool evaluate(double t, const Eigen::VectorXd& x) {
    try {
      src_.derivative(t, x, dx_);
      ok_ = true;
    } catch (const NumericalFailure&) {
      ok_ = false;
    }
    return ok_;
  }

  /// Appends the sample (t, x) of the last evaluate(): q̈, points, targets, force signals, per
  /// row Φ and Φ̇, λ, Q_c, the reactions of material rows and the actuator effort (not a number
  /// where the evaluation failed).
  void record(double t, const Eigen::VectorXd& x) {
    const ForceSet* fs = src_.forces();
    const double nan = std::nan("");
    const bool ok = ok_;
    q_ = x.head(n_);  // workspaces (members): no allocation per sample
    qd_ = x.segment(n_, n_);
    const Eigen::VectorXd& q = q_;
    const Eigen::VectorXd& qd = qd_;
    const double* z = fs && fs->num_states() ? x.data() + src_.z_offset() : nullptr;
    src_.qdd(x, dx_, ok, qdd_);
    plan_.qdd.push_back(qdd_);
    const Data& data = src_.kinematics(q, ok);
    pts_.resize(3 * static_cast<Eigen::Index>(points_.size()));
    for (size_t k = 0; k < points_.size(); ++k) pts_.segment<3>(3 * k) = point_position(src_.model(), data, points_[k]);
    plan_.point_positions.push_back(pts_);
    tg_.resize(static_cast<Eigen::Index>(targets_.size()));
    for (size_t k = 0; k < targets_.size(); ++k) tg_[k] = targets_[k]->eval(t).f;
    plan_.targets.push_back(tg_);
    sig_.resize(static_cast<Eigen::Index>(plan_.force_signals.size()));
    for (size_t k = 0, o = 0; k < signal_elements_.size(); ++k) {
      const int e = signal_elements_[k];
      fs->elements()[e]->signals(t, q, qd, z ? z + fs->state_offset(e) : nullptr, sig_.data() + o);
      o += signal_counts_[k];
    }
    plan_.forces.push_back(sig_);
    if (ok) {
      plan_.phi.push_back(src_.phi());
      plan_.phid.push_back(src_.phid());
      plan_.lambda.push_back(src_.lambda());
      plan_.Qc.push_back(src_.constraint_force());
    } else {
      for (SampleSeries* s : {&plan_.phi, &plan_.phid, &plan_.lambda}) s->push_back(Eigen::VectorXd::Constant(m_, nan));
      plan_.Qc.push_back(Eigen::VectorXd::Constant(n_, nan));
    }
    // Actuator effort: actuator elements + programmed-constraint forces; reaction: material rows.
    act_ = plan_.Qc.back();
    if (any_material_) {
      reaction_.setZero(n_);
      if (ok)
        for (int r = 0; r < m_; ++r)
          if (plan_.material_row[r]) reaction_ -= src_.row_jacobian().row(r).transpose() * src_.lambda()[r];
      if (!ok) reaction_.setConstant(nan);
      act_ -= reaction_;
      plan_.reaction_effort.push_back(reaction_);
    }
    for (int k : actuators_) {
      fs->element_force(k, t, q, qd, z, element_q_, element_zdot_);
      act_ += element_q_;
    }
    plan_.actuator_effort.push_back(act_);
  }

 private:
  Source src_;
  Plan& plan_;
  int n_, m_;
  Eigen::VectorXd dx_, q_, qd_, qdd_, pts_, tg_, sig_, act_, reaction_, element_q_;
  std::vector<double> element_zdot_;
  bool ok_ = false;
  std::vector<int> points_, signal_elements_, actuators_;
  std::vector<size_t> signal_counts_;  ///< per element of signal_elements_: its signals
  std::vector<const TimeFunction*> targets_;
  bool any_material_ = false;
};

/// A plan cut at its first sample beyond the residual tolerance: status, end time, message and
/// the steps kept (with the hint of the caller's order).
void end_at_cut(IntegrationSummary& s, double t_end, double cut_t, double cut_residual, const std::string& rows,
                double tol, const std::string& hint) {
  s.status = IntegrationStatus::ResidualExceeded;
  s.t_end = t_end;
  s.message = "at t = " + fmt(cut_t) + " s the constraint residual max |Phi| = " + fmt(cut_residual) + rows +
              " exceeds integrator.residual_tolerance = " + fmt(tol) +
              ": the plan no longer meets its task; it ends at its last sample within the tolerance, t = " +
              fmt(s.t_end) + " s (hint: " + hint + ")";
}

/// The RK4 stages [q̂, q̂̇, q̂̈] of a plan, recorded for tracking on the same grid (RK4 only):
/// stage s of step k is stored at (4k + s) · 3n, whatever the call order.
class StageRecorder {
 public:
  StageRecorder(ReferenceStages& st, const IntegratorOptions& o, int n, int extra = 0)
      : st_(st), on_(replays_stages(o.method)), per_stage_(3 * static_cast<size_t>(n)),
        extra_(static_cast<size_t>(extra)) {
    if (!on_) return;
    const Rk4Grid grid(o);
    st_.t0 = o.t0;
    st_.h = grid.uniform() ? grid.uniform_step() : (o.t1 - o.t0) / static_cast<double>(grid.steps());
    st_.breakpoints = o.breakpoints;
    if (!grid.uniform())
      for (long k = 0; k < grid.steps(); ++k) ends_.push_back(grid.end(k));
    st_.n = n;
    st_.extra_size = extra;
  }
  bool on() const { return on_; }
  /// The steps completed by time t (a sample's time: a step end).
  long steps_until(double t) const {
    if (ends_.empty()) return std::lround((t - st_.t0) / st_.h);
    return static_cast<long>(std::upper_bound(ends_.begin(), ends_.end(), t) - ends_.begin());
  }
  /// Where this stage's 3n values go (grows the storage as needed).
  double* slot(const Stage& stage) {
    const size_t at = (static_cast<size_t>(stage.step) * 4 + stage.stage) * per_stage_;
    if (st_.data.size() < at + per_stage_) st_.data.resize(std::max(at + per_stage_, 2 * st_.data.size()));
    return st_.data.data() + at;
  }
  /// Where this stage's extra values go ([ż, λ]; null when none are kept).
  double* extra_slot(const Stage& stage) {
    if (extra_ == 0) return nullptr;
    const size_t at = (static_cast<size_t>(stage.step) * 4 + stage.stage) * extra_;
    if (st_.extra.size() < at + extra_) st_.extra.resize(std::max(at + extra_, 2 * st_.extra.size()));
    return st_.extra.data() + at;
  }
  /// Keeps the stages of the steps the plan kept.
  void finish(long steps) {
    if (!on_) return;
    st_.steps = steps;
    st_.data.resize(static_cast<size_t>(steps) * 4 * per_stage_);
    st_.data.shrink_to_fit();
    st_.extra.resize(static_cast<size_t>(steps) * 4 * extra_);
    st_.extra.shrink_to_fit();
  }

 private:
  ReferenceStages& st_;
  bool on_;
  size_t per_stage_, extra_;
  std::vector<double> ends_;  ///< with breakpoints: every step's end (Rk4Grid)
};

/// A run that stopped on a singular or ill-conditioned system: whether the constraint Jacobian A
/// itself is singular at the last valid state (redundant rows or a singular configuration: no
/// partition can help) or regular (then another partition or the Lagrange solver works).
void explain_singular_rows(ReferenceDynamics& rd, const Eigen::VectorXd& x, double t, IntegrationSummary& s) {
  const Model& model = rd.model();
  const int n = rd.nq();
  Data data(model);
  ConstraintEval ev(model, rd.constraint_set());
  const Eigen::VectorXd q = x.head(n), qd = x.segment(n, n);
  evaluate_constraints(model, data, rd.constraint_set(), ev, t, q, qd);
  if (!ev.A.allFinite()) return;
  const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXd>(ev.A).singularValues();
  const double smallest = sv[sv.size() - 1], largest = sv[0];
  std::ostringstream os;
  os << "[";
  for (int i = 0; i < n; ++i) os << (i ? ", " : "") << model.joint_name[i] << " = " << fmt(q[i]);
  os << "]";
  if (!(smallest > 1e-10 * largest))
    s.message = "at t = " + fmt(t) + " s the constraint Jacobian A is singular: its smallest singular value is " +
                fmt(smallest) + " (largest " + fmt(largest) + ") at q = " + os.str() +
                " — the constraints are redundant there or the mechanism is at a singular configuration, and no "
                "partition or solver can help (hint: a task that avoids this configuration). The run ended with: " +
                s.message;
  else if (s.message.find("partition") != std::string::npos)
    s.message += "; the constraint Jacobian A itself is regular there (singular values " + fmt(smallest) + " to " +
                 fmt(largest) + " at q = " + os.str() + "): only this choice of dependent coordinates is singular";
}

/// An RK4 plan that failed (a singular partition, a NaN state, a residual above tolerance) may
/// have failed because its step is outside RK4's stability region for the dynamics (stiff
/// friction, strong Baumgarte gains with a long step): then that is the report, with the
/// eigenvalue, the stable step and the advice, and the symptom follows. A stiff mode may only
/// appear once the motion has started (LuGre's bristles are stiff at speed, not at rest), so the
/// exact Jacobian is checked at the initial state and at up to 64 recorded samples in time
/// order; the earliest unstable one is reported (the closest to the intended motion). The state
/// the run stopped at is not used: it may already be past a singularity or blown up (a task
/// leaving the workspace passes through a singular configuration first). A state where the constraint Jacobian A is (nearly) singular — 1/κ₂(A)
/// below 1e-8, or below 1 % of its value at the first state — ends the search: eigenvalues grow
/// without bound near a singular configuration, and the singularity (a task leaving the
/// workspace), not the step, is the cause (explain_singular_rows). "Stiff" is said when the stable step
/// shrinks below 1 % of the step taken at a later checked state. Returns false when no state
/// shows an unstable step (or no Jacobian can be formed).
bool explain_unstable_step(ReferenceDynamics& rd, const IntegratorOptions& o, const Plan& plan, const Eigen::VectorXd& x0,
                           IntegrationSummary& s) {
  const long nsteps = std::lround(std::ceil((o.t1 - o.t0) / o.step - 1e-9));
  const double h = (o.t1 - o.t0) / nsteps;
  std::vector<std::pair<double, Eigen::VectorXd>> states{{o.t0, x0}};
  const size_t count = plan.x.size(), stride = std::max<size_t>(1, count / 64);
  for (size_t k = 0; k < count; k += stride) states.emplace_back(plan.t[k], plan.x[k]);
  Eigen::MatrixXd J;
  std::optional<StepStability> first;
  double t_first = 0, smallest = std::numeric_limits<double>::infinity(), reference_conditioning = 0;
  for (const auto& [t, x] : states) {
    try {
      rd.jacobian(t, x, J);  // also evaluates the constraints at (t, x)
    } catch (const Error&) {
      continue;  // no Jacobian at this state (a singular partition, an element without one)
    }
    if (!J.allFinite()) continue;
    if (rd.num_constraints() > 0) {  // the conditioning of A: 1/κ₂ against the first state's
      const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXd>(rd.constraints().A).singularValues();
      const double inverse_condition = sv[sv.size() - 1] / sv[0];
      if (!(reference_conditioning > 0)) reference_conditioning = inverse_condition;
      if (!(inverse_condition > 1e-8) || inverse_condition < 1e-2 * reference_conditioning) break;
    }
    const StepStability k = rk4_step_stability(J, h);
    if (k.stable) continue;
    smallest = std::min(smallest, k.largest_stable_step);
    if (!first) first = k, t_first = t;
  }
  if (!first) return false;
  const StepStability& k = *first;
  auto g3 = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.3g", v);
    return std::string(b);
  };
  std::string lam = g3(k.worst.real());
  if (k.worst.imag() != 0) lam += (k.worst.imag() > 0 ? " + " : " - ") + g3(std::abs(k.worst.imag())) + "i";
  const bool stiff = smallest < 0.01 * h;  // not a step a little too long: a stiff mode
  s.message = "the integration is unstable at step h = " + fmt(h) + " s" + (stiff ? ": the problem is stiff" : "") +
              " (from t = " + fmt(t_first) + " s on: there the eigenvalue of df/dx with the largest RK4 amplification is " +
              lam + " 1/s, spectral radius " + g3(k.spectral_radius) + " 1/s, and RK4 is stable only for steps below " +
              g3(k.largest_stable_step) + " s" +
              (stiff ? ", a bound that falls to " + g3(smallest) + " s as the motion goes on): use method: bdf"
                     : "): use a step below " + g3(k.largest_stable_step) + " s (or method: dopri5 or bdf)") +
              ". The run ended with: " + s.message;
  return true;
}

/// What a failed plan's message says beyond the symptom (docs/implicit.md, "When a run fails").
void explain_failure(ReferenceDynamics& rd, const IntegratorOptions& o, const Plan& plan, const Eigen::VectorXd& x0,
                     const Eigen::VectorXd& x_last, double t_last, IntegrationSummary& s) {
  const IntegrationStatus st = s.status;
  if (o.method == IntegratorMethod::RK4 &&
      (st == IntegrationStatus::NumericalFailure || st == IntegrationStatus::NonFinite ||
       st == IntegrationStatus::ResidualExceeded) &&
      explain_unstable_step(rd, o, plan, x0, s))
    return;
  if (st == IntegrationStatus::NumericalFailure && rd.num_constraints() > 0) explain_singular_rows(rd, x_last, t_last, s);
}

}  // namespace

Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const PlanSettings& settings) {
  const IntegratorOptions& options = settings.integrator;
  options.validate();
  check_vector("x0", x0, rd.state_size(), "x0 = [q; qd; z], see ReferenceDynamics::make_state");
  const int n = rd.nq();
  Plan plan;
  PlanRecorder<SecondOrderSource> recorder(SecondOrderSource{rd}, plan, settings.record);
  recorder.reserve(settings.integrator);
  const int nz = rd.num_force_states(), m = rd.num_constraints();
  StageRecorder stages(plan.stages, options, n, nz + m);
  auto rhs = [&](const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    rd.derivative(t, x, dx);
    if (stages.on()) {
      double* s = stages.slot(stage);
      std::copy(x.data(), x.data() + 2 * n, s);
      std::copy(dx.data() + n, dx.data() + 2 * n, s + 2 * n);
      if (double* e = stages.extra_slot(stage)) {
        std::copy(dx.data() + 2 * n, dx.data() + 2 * n + nz, e);
        const Eigen::VectorXd& lam = rd.lambda();
        for (int r = 0; r < m; ++r) e[nz + r] = r < lam.size() ? lam[r] : 0.0;
      }
    }
  };
  double worst = 0;
  // The first sample (t >= residual_from) whose residual exceeds the tolerance (or is not a
  // number) is not recorded: the plan ends at the sample before, its last trustworthy one. The
  // initial state is always recorded (build_problem checked it against initial.tolerance).
  const double tol = settings.record.residual_tolerance;
  bool cut = false;
  double cut_t = 0, cut_residual = 0;
  std::string cut_why;
  auto obs = [&](double t, const Eigen::VectorXd& x) {
    if (t >= settings.residual_from - 1e-12) {
      double r = 0;
      try {
        r = rd.residual(t, x);
      } catch (const NumericalFailure& e) {
        if (!std::isfinite(tol)) throw;
        r = std::nan("");
        cut_why = e.what();
      }
      if (!(r <= tol) && !plan.t.empty()) {
        cut = true, cut_t = t, cut_residual = r;
        return false;
      }
      if (!std::isnan(r)) worst = std::max(worst, r);
    }
    plan.t.push_back(t);
    plan.x.push_back(x);
    recorder.evaluate(t, x);
    recorder.record(t, x);
    if (settings.progress) settings.progress(t);
    return true;
  };
  Eigen::VectorXd x = x0;
  OdeJacobian jacobian;
  if (options.method == IntegratorMethod::BDF)
    jacobian = [&rd](double t, const Eigen::VectorXd& xx, Eigen::MatrixXd& J) { rd.jacobian(t, xx, J); };
  OdeProjection projection;
  long projections = 0;
  double largest_correction = 0;
  if (rd.options().stabilization != Stabilization::Baumgarte)
    projection = [&](double t, Eigen::VectorXd& xx) {
      const ReferenceDynamics::StateProjection p = rd.project_state(t, xx);
      if (p.iterations > 0) ++projections;
      largest_correction = std::max({largest_correction, p.dq, p.dqd});
    };
  plan.summary = integrate_staged(rhs, x, options, obs, jacobian, projection);
  plan.summary.projections = projections;
  plan.summary.max_projection_correction = largest_correction;
  if (cut) {
    end_at_cut(plan.summary, plan.t.empty() ? options.t0 : plan.t.back(), cut_t, cut_residual,
               cut_why.empty() ? std::string() : " (" + cut_why + ")", tol,
               "a smaller step, stronger Baumgarte gains, or a task that stays in the workspace");
    if (stages.on()) plan.summary.steps = stages.steps_until(plan.summary.t_end);
  }
  stages.finish(plan.summary.steps);
  plan.summary.max_constraint_residual = worst;
  explain_failure(rd, options, plan, x0, x, plan.summary.t_end, plan.summary);
  return plan;
}

Plan plan_jerk_motion(JerkDynamics& jd, const Eigen::VectorXd& x0, const PlanSettings& settings) {
  const IntegratorOptions& options = settings.integrator;
  options.validate();
  check_vector("x0", x0, jd.state_size(), "x0 = [q; qd; qdd; z], see JerkDynamics::initial_state");
  const ConstraintSet& cs = jd.constraint_set();
  const int n = jd.nq(), m = jd.num_constraints();
  Plan plan;
  PlanRecorder<JerkSource> recorder(JerkSource{jd}, plan, settings.record);
  recorder.reserve(settings.integrator);
  StageRecorder stages(plan.stages, options, n);  // x[0, 3n) is [q̂, q̂̇, q̂̈] at every stage
  double worst = 0;
  auto rhs = [&](const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
    jd.derivative(t, x, xdot);
    if (stages.on()) std::copy(x.data(), x.data() + 3 * n, stages.slot(stage));
  };
  // Rows of order ≤ 2 (their |Phi|, |c| or |B q̈ + s|) are checked against the tolerance as in
  // plan_motion: the first sample beyond it is not recorded and the plan ends before it.
  std::vector<int> lower_rows;
  if (cs.rows() == m)
    for (int r = 0; r < m; ++r)
      if (cs.row_order(r) <= 2) lower_rows.push_back(r);
  const double tol = settings.record.residual_tolerance;
  bool cut = false;
  double cut_t = 0, cut_residual = 0;
  auto obs = [&](double t, const Eigen::VectorXd& x) {
    const bool ok = recorder.evaluate(t, x);
    if (!lower_rows.empty() && t >= settings.residual_from - 1e-12 && std::isfinite(tol) && !plan.t.empty()) {
      double r = ok ? 0.0 : std::nan("");
      if (ok)
        for (int row : lower_rows) r = std::max(r, std::abs(jd.row_residual()[row]));
      if (!(r <= tol)) {
        cut = true, cut_t = t, cut_residual = r;
        return false;
      }
    }
    plan.t.push_back(t);
    plan.x.push_back(x);
    recorder.record(t, x);
    if (ok) {
      worst = std::max(worst, jd.dynamics_residual());
      for (int r = 0; r < m; ++r) worst = std::max(worst, std::abs(jd.row_residual()[r]));
    }
    if (settings.progress) settings.progress(t);
    return true;
  };
  Eigen::VectorXd x = x0;
  plan.summary = integrate_staged(rhs, x, options, obs);
  if (cut) {
    end_at_cut(plan.summary, plan.t.back(), cut_t, cut_residual, " of the rows of order <= 2", tol,
               "a smaller step — at the jerk level these rows are stabilized by d/dt psi + kappa psi = 0 and the "
               "Baumgarte gains, whose fastest mode RK4 must resolve — weaker gains, or a task that stays in the "
               "workspace");
    if (stages.on()) plan.summary.steps = stages.steps_until(plan.summary.t_end);
  }
  stages.finish(plan.summary.steps);
  plan.summary.max_constraint_residual = worst;
  return plan;
}

}  // namespace refdyn
