// plan_motion and plan_jerk_motion (plan.hpp): a reference dynamics integrated and recorded.
#include "refdyn/simulate/plan.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace refdyn {

namespace {

/// Records the reference dynamics' quantities at output samples into a Plan.
class PlanRecorder {
 public:
  PlanRecorder(ReferenceDynamics& rd, Plan& plan, const RecordOptions& o)
      : rd_(rd), plan_(plan), model_(rd.model()), n_(rd.nq()), m_(rd.num_constraints()), dx_(rd.state_size()),
        q_(n_), qd_(n_) {
    const ConstraintSet& cs = rd.constraint_set();
    const ForceSet& fs = rd.forces();
    plan.joints = model_.joint_name;
    plan.state_names = fs.state_names();
    for (int p : o.points) {
      if (p < 0 || p >= static_cast<int>(model_.point_name.size()))
        throw Error(expected_got("recorded point index", "0.." + std::to_string(model_.point_name.size()) + " (exclusive)",
                                 std::to_string(p)));
      plan.points.push_back(model_.point_name[p]);
    }
    points_ = o.points;
    for (int r = 0; r < m_; ++r) {
      plan.constraint_rows.push_back(cs.row_name(r));
      const bool mat = cs.constraints()[cs.row_owner(r)]->origin == ConstraintOrigin::Material;
      plan.material_row.push_back(mat ? 1 : 0);
      any_material_ = any_material_ || mat;
    }
    for (const auto& c : cs.constraints())
      if (!c->record_as.empty() && c->target()) {
        plan.target_signals.push_back(c->record_as);
        targets_.push_back(c->target());
      }
    for (size_t k = 0; k < fs.elements().size(); ++k) {
      const auto& e = fs.elements()[k];
      const auto names = e->signal_names();
      if (!names.empty()) signal_elements_.push_back(static_cast<int>(k));
      plan.force_signals.insert(plan.force_signals.end(), names.begin(), names.end());
      if (e->actuator()) actuators_.push_back(static_cast<int>(k));
    }
  }

  void record(double t, const Eigen::VectorXd& x) {
    const ForceSet& fs = rd_.forces();
    bool ok = true;
    try {
      rd_.derivative(t, x, dx_);
    } catch (const NumericalFailure&) {
      ok = false;
    }
    const double nan = std::nan("");
    q_ = x.head(n_);
    qd_ = x.segment(n_, n_);
    const double* z = fs.num_states() ? x.data() + 2 * n_ : nullptr;
    plan_.qdd.push_back(ok ? Eigen::VectorXd(dx_.segment(n_, n_)) : Eigen::VectorXd::Constant(n_, nan));
    Eigen::VectorXd pts(3 * points_.size());
    if (!ok) forward_kinematics(model_, rd_.data(), q_);  // the failed evaluation may not have reached the kinematics
    for (size_t k = 0; k < points_.size(); ++k) pts.segment<3>(3 * k) = point_position(model_, rd_.data(), points_[k]);
    plan_.point_positions.push_back(std::move(pts));
    Eigen::VectorXd tg(targets_.size());
    for (size_t k = 0; k < targets_.size(); ++k) tg[k] = targets_[k]->eval(t).f;
    plan_.targets.push_back(std::move(tg));
    Eigen::VectorXd sig(plan_.force_signals.size());
    for (size_t k = 0, o = 0; k < signal_elements_.size(); ++k) {
      const int e = signal_elements_[k];
      fs.elements()[e]->signals(t, q_, qd_, z ? z + fs.state_offset(e) : nullptr, sig.data() + o);
      o += fs.elements()[e]->signal_names().size();
    }
    plan_.forces.push_back(std::move(sig));
    const ConstraintEval& ev = rd_.constraints();
    plan_.phi.push_back(ok ? ev.phi : Eigen::VectorXd::Constant(m_, nan));
    plan_.phid.push_back(ok ? ev.phid : Eigen::VectorXd::Constant(m_, nan));
    plan_.lambda.push_back(ok ? rd_.lambda() : Eigen::VectorXd::Constant(m_, nan));
    plan_.Qc.push_back(ok ? rd_.constraint_force() : Eigen::VectorXd::Constant(n_, nan));
    // Actuator effort: actuator elements + programmed-constraint forces; reaction: material rows.
    Eigen::VectorXd act = plan_.Qc.back();
    if (any_material_) {
      Eigen::VectorXd reaction = Eigen::VectorXd::Zero(n_);
      if (ok)
        for (int r = 0; r < m_; ++r)
          if (plan_.material_row[r]) reaction -= ev.A.row(r).transpose() * rd_.lambda()[r];
      if (!ok) reaction.setConstant(nan);
      act -= reaction;
      plan_.reaction_effort.push_back(std::move(reaction));
    }
    for (int k : actuators_) act += fs.element_force(k, t, q_, qd_, z);
    plan_.actuator_effort.push_back(std::move(act));
  }

 private:
  ReferenceDynamics& rd_;
  Plan& plan_;
  const Model& model_;
  int n_, m_;
  Eigen::VectorXd dx_, q_, qd_;
  std::vector<int> points_, signal_elements_, actuators_;
  std::vector<const TimeFunction*> targets_;
  bool any_material_ = false;
};

}  // namespace

Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const IntegratorOptions& options,
                 double residual_from, const std::function<void(double)>& progress, const RecordOptions& record) {
  options.validate();
  check_vector("x0", x0, rd.state_size(), "x0 = [q; qd; z], see ReferenceDynamics::make_state");
  const int n = rd.nq();
  Plan plan;
  PlanRecorder recorder(rd, plan, record);
  const bool rk4 = options.method == IntegratorMethod::RK4;
  ReferenceStages& st = plan.stages;
  if (rk4) {
    const long nsteps = std::lround(std::ceil((options.t1 - options.t0) / options.step - 1e-9));
    st.t0 = options.t0;
    st.h = (options.t1 - options.t0) / nsteps;
    st.n = n;
  }
  const size_t per_stage = 3 * static_cast<size_t>(n);
  // The stage hook: RK4 stage s of step k is stored at (4k + s) · 3n, whatever the call order.
  auto rhs = [&](const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    rd.derivative(t, x, dx);
    if (rk4) {
      const size_t at = (static_cast<size_t>(stage.step) * 4 + stage.stage) * per_stage;
      if (st.data.size() < at + per_stage) st.data.resize(std::max(at + per_stage, 2 * st.data.size()));
      std::copy(x.data(), x.data() + 2 * n, st.data.data() + at);
      std::copy(dx.data() + n, dx.data() + 2 * n, st.data.data() + at + 2 * n);
    }
  };
  double worst = 0;
  // The first sample (t >= residual_from) whose residual exceeds the tolerance (or is not a
  // number) is not recorded: the plan ends at the sample before, its last trustworthy one. The
  // initial state is always recorded (build_problem checked it against initial.tolerance).
  const double tol = record.residual_tolerance;
  bool cut = false;
  double cut_t = 0, cut_residual = 0;
  std::string cut_why;
  auto obs = [&](double t, const Eigen::VectorXd& x) {
    if (t >= residual_from - 1e-12) {
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
    recorder.record(t, x);
    if (progress) progress(t);
    return true;
  };
  Eigen::VectorXd x = x0;
  plan.summary = integrate_staged(rhs, x, options, obs);
  if (cut) {
    IntegrationSummary& s = plan.summary;
    s.status = IntegrationStatus::ResidualExceeded;
    s.t_end = plan.t.empty() ? options.t0 : plan.t.back();
    s.message = "at t = " + fmt(cut_t) + " s the constraint residual max |Phi| = " + fmt(cut_residual) +
                (cut_why.empty() ? std::string() : " (" + cut_why + ")") + " exceeds integrator.residual_tolerance = " +
                fmt(tol) + ": the plan no longer meets its task; it ends at its last sample within the tolerance, t = " +
                fmt(s.t_end) + " s (hint: a smaller step, stronger Baumgarte gains, or a task that stays in the "
                "workspace)";
    if (rk4) s.steps = std::lround((s.t_end - options.t0) / st.h);
  }
  if (rk4) {
    st.steps = plan.summary.steps;
    st.data.resize(static_cast<size_t>(st.steps) * 4 * per_stage);
    st.data.shrink_to_fit();
  }
  plan.summary.max_constraint_residual = worst;
  return plan;
}

Plan plan_jerk_motion(JerkDynamics& jd, const Eigen::VectorXd& x0, const IntegratorOptions& options,
                      const RecordOptions& record, const std::function<void(double)>& progress) {
  options.validate();
  check_vector("x0", x0, jd.state_size(), "x0 = [q; qd; qdd], see JerkDynamics::initial_state");
  const Model& model = jd.model();
  const ForceSet* forces = jd.forces();
  const int n = jd.nq(), m = jd.num_constraints();
  Plan plan;
  plan.joints = model.joint_name;
  for (int j = 0; j < n; ++j) plan.state_names.push_back("acc_" + model.joint_name[j]);
  for (int p : record.points) plan.points.push_back(model.point_name[p]);
  for (const auto& c : jd.constraints()) {
    plan.constraint_rows.push_back(c->name());
    plan.material_row.push_back(0);
  }
  Data data(model);
  Eigen::VectorXd dx(jd.state_size());
  double worst = 0;
  auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) { jd.derivative(t, x, xdot); };
  auto obs = [&](double t, const Eigen::VectorXd& x) {
    const double nan = std::nan("");
    bool ok = true;
    try {
      jd.derivative(t, x, dx);
    } catch (const NumericalFailure&) {
      ok = false;
    }
    plan.t.push_back(t);
    plan.x.push_back(x);
    plan.qdd.push_back(x.segment(2 * n, n));
    const Eigen::VectorXd q = x.head(n);
    forward_kinematics(model, data, q);
    Eigen::VectorXd pts(3 * record.points.size());
    for (size_t k = 0; k < record.points.size(); ++k) pts.segment<3>(3 * k) = point_position(model, data, record.points[k]);
    plan.point_positions.push_back(std::move(pts));
    plan.targets.emplace_back();
    plan.forces.emplace_back();
    plan.phi.push_back(ok ? jd.row_residual() : Eigen::VectorXd::Constant(m, nan));
    plan.phid.push_back(plan.phi.back());
    plan.lambda.push_back(ok ? jd.lambda() : Eigen::VectorXd::Constant(m, nan));
    plan.Qc.push_back(ok ? jd.constraint_force() : Eigen::VectorXd::Constant(n, nan));
    Eigen::VectorXd act = plan.Qc.back();
    if (forces)
      for (int k = 0; k < static_cast<int>(forces->elements().size()); ++k)
        if (forces->elements()[k]->actuator()) act += forces->element_force(k, t, q, x.segment(n, n), nullptr);
    plan.actuator_effort.push_back(std::move(act));
    if (ok) worst = std::max(worst, jd.dynamics_residual());
    if (progress) progress(t);
    return true;
  };
  Eigen::VectorXd x = x0;
  plan.summary = integrate(rhs, x, options, obs);
  plan.summary.max_constraint_residual = worst;
  return plan;
}

}  // namespace refdyn
