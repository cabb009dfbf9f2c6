#include "refdyn/control.hpp"

#include "refdyn/error.hpp"
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

Plan plan_motion(ReferenceDynamics& rd, const Eigen::VectorXd& x0, const IntegratorOptions& options,
                 double residual_from, const std::function<void(double)>& progress) {
  options.validate();
  check_vector("x0", x0, rd.state_size(), "x0 = [q; qd; z], see ReferenceDynamics::make_state");
  const int n = rd.nq();
  Plan plan;
  const bool rk4 = options.method == IntegratorMethod::RK4;
  if (rk4) {
    const long nsteps = std::lround(std::ceil((options.t1 - options.t0) / options.step - 1e-9));
    plan.stages.t0 = options.t0;
    plan.stages.h = (options.t1 - options.t0) / nsteps;
    plan.stages.n = n;
    plan.stages.data.reserve(static_cast<size_t>(nsteps) * 4 * 3 * n);
  }
  auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    rd.derivative(t, x, dx);
    if (rk4) {
      auto& d = plan.stages.data;
      d.insert(d.end(), x.data(), x.data() + 2 * n);
      d.insert(d.end(), dx.data() + n, dx.data() + 2 * n);
    }
  };
  Eigen::VectorXd dx(rd.state_size());
  double worst = 0;
  auto obs = [&](double t, const Eigen::VectorXd& x) {
    plan.t.push_back(t);
    plan.x.push_back(x);
    if (t >= residual_from - 1e-12) worst = std::max(worst, rd.residual(t, x));
    if (progress) progress(t);
    return true;
  };
  Eigen::VectorXd x = x0;
  plan.summary = integrate(rhs, x, options, obs);
  if (rk4) {
    plan.stages.steps = plan.summary.steps;
    plan.stages.data.resize(static_cast<size_t>(plan.stages.steps) * 4 * 3 * n);
  }
  // q̂̈ at the samples: stage 1 of each recorded step is the derivative at that sample.
  const long every = rk4 && options.output_interval > 0
                         ? std::max(1L, std::lround(options.output_interval / plan.stages.h))
                         : 1L;
  for (size_t k = 0; k < plan.t.size(); ++k) {
    const long step = static_cast<long>(k) * every;
    if (rk4 && step < plan.stages.steps) {
      plan.qdd.push_back(Eigen::Map<const Eigen::VectorXd>(plan.stages.stage(step, 0) + 2 * n, n));
    } else {
      try {
        rd.derivative(plan.t[k], plan.x[k], dx);
        plan.qdd.push_back(dx.segment(n, n));
      } catch (const NumericalFailure&) {
        plan.qdd.push_back(Eigen::VectorXd::Constant(n, std::nan("")));
      }
    }
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

// τ from the controller, saturated; returns true when a joint was saturated. With `plant`, the
// plant's M and c + g at this state are already in w.data and the controller may reuse them.
bool control(Controller& c, PlantWorkspace& w, double t, const Eigen::VectorXd& limit,
             const Model* plant = nullptr) {
  const ReferenceSample ref{w.qr, w.qdr, w.qddr};
  if (plant)
    c.compute_with_dynamics(t, w.q, w.qd, ref, *plant, w.data, w.tau);
  else
    c.compute(t, w.q, w.qd, ref, w.tau);
  bool sat = false;
  for (int i = 0; i < limit.size(); ++i) {
    if (w.tau[i] > limit[i]) w.tau[i] = limit[i], sat = true;
    if (w.tau[i] < -limit[i]) w.tau[i] = -limit[i], sat = true;
  }
  return sat;
}

// Plant ẋ from (t, x) with the reference already in w.qr/qdr/qddr.
void plant_derivative(const Model& m, const ForceSet& forces, Controller& c, PlantWorkspace& w,
                      const Eigen::VectorXd& limit, double t, const double* x, double* dx) {
  const int n = m.nv, nz = forces.num_states();
  w.q = Eigen::Map<const Eigen::VectorXd>(x, n);
  w.qd = Eigen::Map<const Eigen::VectorXd>(x + n, n);
  unchecked::mass_matrix_and_bias(m, w.data, w.q, w.qd);
  control(c, w, t, limit, &m);
  forces.evaluate(t, w.q, w.qd, nz ? x + 2 * n : nullptr, w.Q, w.zdot.data());
  w.data.ddq = w.tau + w.Q - w.data.nle;
  if (!unchecked::solve_mass_matrix(w.data, w.data.ddq))
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
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
  const int n = plant.nv, nz = plant_forces.num_states();
  check_vector("plant initial state", x0_plant, 2 * n + nz, "x0 = [q; qd; z_plant]");
  if (options.effort_limit.size() != 0) {
    check_vector("effort_limit", options.effort_limit, n, "one |tau| limit per joint, or none");
    for (int i = 0; i < n; ++i)
      if (!(options.effort_limit[i] >= 0))
        throw Error(expected_got("effort_limit[" + std::to_string(i) + "]", "a value >= 0", fmt(options.effort_limit[i])));
  }
  if (plan.x.empty()) throw Error("simulate_closed_loop: the plan is empty (hint: check plan.summary)");
  if (plan.x.front().size() < 2 * n) throw Error("simulate_closed_loop: the plan's model has fewer coordinates than the plant");
  ClosedLoopResult out;
  PlantWorkspace w(plant, plant_forces);
  const auto start = std::chrono::steady_clock::now();

  auto set_ref = [&](const double* q, const double* qd, const double* qdd) {
    w.qr = Eigen::Map<const Eigen::VectorXd>(q, n);
    w.qdr = Eigen::Map<const Eigen::VectorXd>(qd, n);
    w.qddr = Eigen::Map<const Eigen::VectorXd>(qdd, n);
  };
  auto record = [&](double t, const double* xp) {
    out.t.push_back(t);
    out.x.push_back(Eigen::Map<const Eigen::VectorXd>(xp, 2 * n + nz));
    w.q = Eigen::Map<const Eigen::VectorXd>(xp, n);
    w.qd = Eigen::Map<const Eigen::VectorXd>(xp + n, n);
    if (control(controller, w, t, options.effort_limit)) ++out.saturated_samples;
    out.tau.push_back(w.tau);
    out.q_ref.push_back(w.qr);
    out.qd_ref.push_back(w.qdr);
    if (options.progress) options.progress(t);
  };

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
    long calls = 0;
    auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
      const double* s = st.stage(calls / 4, static_cast<int>(calls % 4));
      ++calls;
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
    Eigen::VectorXd x = x0_plant;
    out.summary = integrate(rhs, x, o, obs);
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
    Eigen::VectorXd x(nr + 2 * n + nz);
    x.head(nr) = plan.x.front();
    x.tail(2 * n + nz) = x0_plant;
    out.summary = integrate(rhs, x, io, obs);
  }
  out.summary.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace refdyn
