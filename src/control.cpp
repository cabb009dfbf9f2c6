#include "refdyn/control.hpp"

#include "refdyn/error.hpp"
#include "refdyn/kinematics.hpp"
#include "refdyn/recursive_dynamics.hpp"
#include "refdyn/text.hpp"

#include <chrono>
#include <cmath>

namespace refdyn {

ComputedTorquePD::ComputedTorquePD(const Model& model, Eigen::VectorXd delta)
    : model_(model), data_(model), delta_(std::move(delta)), u_(Eigen::VectorXd::Zero(model.nv)) {
  check_vector("computed-torque gains delta", delta_, model.nv, "one gain per joint [1/s]");
  for (int i = 0; i < model.nv; ++i)
    if (delta_[i] < 0)
      throw Error(expected_got("computed-torque gain delta[" + std::to_string(i) + "]", "a value >= 0", fmt(delta_[i])));
}

void ComputedTorquePD::outer_loop(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r) {
  // u = q̂̈ − 2δ ė − δ² e
  for (int i = 0; i < model_.nv; ++i) {
    const double e = q[i] - r.q[i], ed = qd[i] - r.qd[i];
    u_[i] = r.qdd[i] - 2.0 * delta_[i] * ed - delta_[i] * delta_[i] * e;
  }
}

void ComputedTorquePD::compute(double, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                               Eigen::VectorXd& tau) {
  outer_loop(q, qd, r);
  unchecked::mass_matrix_and_bias(model_, data_, q, qd);
  tau.noalias() = data_.M.lazyProduct(u_);
  tau += data_.nle;
}

void ComputedTorquePD::compute_with_dynamics(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                             const ReferenceSample& r, const Model& model, const Data& dynamics,
                                             Eigen::VectorXd& tau) {
  if (&model != &model_) return compute(t, q, qd, r, tau);
  outer_loop(q, qd, r);
  tau.noalias() = dynamics.M.lazyProduct(u_);
  tau += dynamics.nle;
}

PDGravity::PDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd kd)
    : model_(model), data_(model), kp_(std::move(kp)), kd_(std::move(kd)) {
  check_vector("PD gains kp", kp_, model.nv);
  check_vector("PD gains kd", kd_, model.nv);
}

void PDGravity::compute(double, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                        Eigen::VectorXd& tau) {
  unchecked::rnea(model_, data_, q, nullptr, nullptr, true, data_.g);
  tau = data_.g - kp_.cwiseProduct(q - r.q) - kd_.cwiseProduct(qd - r.qd);
}

PIDGravity::PIDGravity(const Model& model, Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd)
    : model_(model), data_(model), kp_(std::move(kp)), ki_(std::move(ki)), kd_(std::move(kd)) {
  check_vector("PID gains kp", kp_, model.nv);
  check_vector("PID gains ki", ki_, model.nv);
  check_vector("PID gains kd", kd_, model.nv);
}

std::vector<std::string> PIDGravity::state_names() const {
  std::vector<std::string> n;
  for (const auto& j : model_.joint_name) n.push_back("xi_" + j);
  return n;
}

void PIDGravity::compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& r,
                         Eigen::VectorXd& tau) {
  unchecked::rnea(model_, data_, q, nullptr, nullptr, true, data_.g);
  tau = data_.g - kp_.cwiseProduct(q - r.q) - kd_.cwiseProduct(qd - r.qd);
}

void PIDGravity::compute_with_state(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                    const ReferenceSample& r, const double* xc, double* xc_dot, const Model&,
                                    const Data*, Eigen::VectorXd& tau) {
  compute(t, q, qd, r, tau);
  for (int i = 0; i < model_.nv; ++i) {
    tau[i] -= ki_[i] * xc[i];
    if (xc_dot) xc_dot[i] = q[i] - r.q[i];
  }
}

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

namespace {

struct PlantWorkspace {
  PlantWorkspace(const Model& m, const ForceSet& f)
      : data(m), q(m.nv), qd(m.nv), tau(m.nv), Q(m.nv), zdot(std::max(1, f.num_states())),
        qr(m.nv), qdr(m.nv), qddr(m.nv) {}
  Data data;
  Eigen::VectorXd q, qd, tau, Q, zdot, qr, qdr, qddr;
};

// τ from the controller, saturated; returns true when a joint was saturated. With `dynamics`,
// the plant's M and c + g at this state are in it and the controller may reuse them. xc: the
// controller's states, xc_dot: their derivatives (null: not needed).
bool control(Controller& c, PlantWorkspace& w, double t, const Eigen::VectorXd& limit, const Model& plant,
             const Data* dynamics, const double* xc, double* xc_dot) {
  const ReferenceSample ref{w.qr, w.qdr, w.qddr};
  c.compute_with_state(t, w.q, w.qd, ref, xc, xc_dot, plant, dynamics, w.tau);
  bool sat = false;
  for (int i = 0; i < limit.size(); ++i) {
    if (w.tau[i] > limit[i]) w.tau[i] = limit[i], sat = true;
    if (w.tau[i] < -limit[i]) w.tau[i] = -limit[i], sat = true;
  }
  return sat;
}

// Plant ẋ from (t, x), x = [q; q̇; z_plant; xc], with the reference already in w.qr/qdr/qddr.
void plant_derivative(const Model& m, const ForceSet& forces, Controller& c, PlantWorkspace& w,
                      const Eigen::VectorXd& limit, double t, const double* x, double* dx) {
  const int n = m.nv, nz = forces.num_states(), nc = c.num_states();
  w.q = Eigen::Map<const Eigen::VectorXd>(x, n);
  w.qd = Eigen::Map<const Eigen::VectorXd>(x + n, n);
  if (forward_dynamics_uses_aba(n) && !c.reuses_dynamics(m)) {  // articulated-body algorithm: no M needed
    control(c, w, t, limit, m, nullptr, nc ? x + 2 * n + nz : nullptr, nc ? dx + 2 * n + nz : nullptr);
    forces.evaluate(t, w.q, w.qd, nz ? x + 2 * n : nullptr, w.Q, w.zdot.data());
    w.Q += w.tau;
    if (unchecked::aba(m, w.data, w.q, w.qd, w.Q, w.data.ddq) >= 0)
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
  } else {  // the controller reuses M and c + g: CRBA + Cholesky
    unchecked::mass_matrix_and_bias(m, w.data, w.q, w.qd);
    control(c, w, t, limit, m, &w.data, nc ? x + 2 * n + nz : nullptr, nc ? dx + 2 * n + nz : nullptr);
    forces.evaluate(t, w.q, w.qd, nz ? x + 2 * n : nullptr, w.Q, w.zdot.data());
    w.data.ddq = w.tau + w.Q - w.data.nle;
    if (!unchecked::solve_mass_matrix(w.data, w.data.ddq))
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
  }
  Eigen::Map<Eigen::VectorXd>(dx, n) = w.qd;
  Eigen::Map<Eigen::VectorXd>(dx + n, n) = w.data.ddq;
  for (int k = 0; k < nz; ++k) dx[2 * n + k] = w.zdot[k];
}

}  // namespace

ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, ReferenceDynamics* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options) {
  const IntegratorOptions& io = options.integrator;
  io.validate();
  const int n = plant.nv, nz = plant_forces.num_states(), nc = controller.num_states();
  const int nx = 2 * n + nz + nc;
  if (x0_plant.size() != nx) check_vector("plant initial state", x0_plant, 2 * n + nz, "x0 = [q; qd; z_plant]");
  check_finite("plant initial state", x0_plant);
  if (options.effort_limit.size() != 0) {
    check_vector("effort_limit", options.effort_limit, n, "one |tau| limit per joint, or none");
    for (int i = 0; i < n; ++i)
      if (!(options.effort_limit[i] >= 0))
        throw Error(expected_got("effort_limit[" + std::to_string(i) + "]", "a value >= 0", fmt(options.effort_limit[i])));
  }
  if (plan.x.empty()) throw Error("simulate_closed_loop: the plan is empty (hint: check plan.summary)");
  if (plan.x.front().size() < 2 * n) throw Error("simulate_closed_loop: the plan's model has fewer coordinates than the plant");
  for (int p : options.points)
    if (p < 0 || p >= static_cast<int>(plant.point_name.size()))
      throw Error(expected_got("recorded point index", "0.." + std::to_string(plant.point_name.size()) + " (exclusive)",
                               std::to_string(p)));
  ClosedLoopResult out;
  out.joints = plant.joint_name;
  out.state_names = plant_forces.state_names();
  for (const auto& s : controller.state_names()) out.state_names.push_back(s);
  for (int p : options.points) out.points.push_back(plant.point_name[p]);
  PlantWorkspace w(plant, plant_forces);
  Data kin(plant);
  const auto start = std::chrono::steady_clock::now();

  auto set_ref = [&](const double* q, const double* qd, const double* qdd) {
    w.qr = Eigen::Map<const Eigen::VectorXd>(q, n);
    w.qdr = Eigen::Map<const Eigen::VectorXd>(qd, n);
    w.qddr = Eigen::Map<const Eigen::VectorXd>(qdd, n);
  };
  auto record = [&](double t, const double* xp) {
    out.t.push_back(t);
    out.x.push_back(Eigen::Map<const Eigen::VectorXd>(xp, nx));
    w.q = Eigen::Map<const Eigen::VectorXd>(xp, n);
    w.qd = Eigen::Map<const Eigen::VectorXd>(xp + n, n);
    if (control(controller, w, t, options.effort_limit, plant, nullptr, nc ? xp + 2 * n + nz : nullptr, nullptr))
      ++out.saturated_samples;
    out.tau.push_back(w.tau);
    out.q_ref.push_back(w.qr);
    out.qd_ref.push_back(w.qdr);
    Eigen::VectorXd pts(3 * options.points.size());
    if (!options.points.empty()) {
      forward_kinematics(plant, kin, w.q);
      for (size_t k = 0; k < options.points.size(); ++k)
        pts.segment<3>(3 * k) = point_position(plant, kin, options.points[k]);
    }
    out.point_positions.push_back(std::move(pts));
    if (options.progress) options.progress(t);
  };
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(nx);
  x0.head(x0_plant.size()) = x0_plant;

  if (io.method == IntegratorMethod::RK4) {
    const ReferenceStages& st = plan.stages;
    if (st.steps == 0 || st.n != n)
      throw Error("simulate_closed_loop: the plan has no recorded RK4 stages for this plant (hint: plan with RK4)");
    const long nsteps = std::lround(std::ceil((io.t1 - io.t0) / io.step - 1e-9));
    const double h = (io.t1 - io.t0) / nsteps;
    if (std::abs(io.t0 - st.t0) > 1e-12 || std::abs(h - st.h) > 1e-12 * st.h)
      throw Error(expected_got("closed-loop RK4 grid", "t0 = " + fmt(st.t0) + " and step = " + fmt(st.h) + " (the plan's)",
                               "t0 = " + fmt(io.t0) + ", step = " + fmt(h)));
    // Samples beyond the recorded stages use the plan's samples (only the final time).
    const long usable = std::min<long>(nsteps, st.steps);
    IntegratorOptions o = io;
    o.t1 = io.t0 + usable * h;
    // The stage hook says which recorded reference stage belongs to this evaluation.
    auto rhs = [&](const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
      const double* s = st.stage(stage.step, stage.stage);
      set_ref(s, s + n, s + 2 * n);
      plant_derivative(plant, plant_forces, controller, w, options.effort_limit, t, x.data(), dx.data());
    };
    const long every = io.output_interval > 0 ? std::max(1L, std::lround(io.output_interval / h)) : 1L;
    long sample = 0;
    auto obs = [&](double t, const Eigen::VectorXd& x) {
      const long step = sample * every;
      ++sample;
      if (step < st.steps) {
        const double* s = st.stage(step, 0);
        set_ref(s, s + n, s + 2 * n);
      } else {  // the plan's last sample
        const Eigen::VectorXd& xr = plan.x.back();
        set_ref(xr.data(), xr.data() + n, plan.qdd.back().data());
      }
      record(t, x.data());
      return true;
    };
    Eigen::VectorXd x = x0;
    out.summary = integrate_staged(rhs, x, o, obs);
    if (out.summary.ok() && usable < nsteps) {
      out.summary.status = IntegrationStatus::Stopped;
      out.summary.message = "the plan ends at t = " + fmt(o.t1) + " s, before the requested t1 = " + fmt(io.t1) + " s";
    }
  } else {
    if (!rd) throw Error("simulate_closed_loop: Dormand–Prince needs the ReferenceDynamics to integrate jointly");
    const int nr = rd->state_size();
    Eigen::VectorXd xr(nr), dxr(nr);
    auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
      xr = x.head(nr);
      rd->derivative(t, xr, dxr);
      dx.head(nr) = dxr;
      set_ref(xr.data(), xr.data() + n, dxr.data() + n);
      plant_derivative(plant, plant_forces, controller, w, options.effort_limit, t, x.data() + nr, dx.data() + nr);
    };
    auto obs = [&](double t, const Eigen::VectorXd& x) {
      xr = x.head(nr);
      rd->derivative(t, xr, dxr);
      set_ref(xr.data(), xr.data() + n, dxr.data() + n);
      record(t, x.data() + nr);
      return true;
    };
    Eigen::VectorXd x(nr + nx);
    x.head(nr) = plan.x.front();
    x.tail(nx) = x0;
    out.summary = integrate(rhs, x, io, obs);
  }
  out.summary.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace refdyn
