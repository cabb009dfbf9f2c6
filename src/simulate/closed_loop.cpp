// simulate_closed_loop (closed_loop.hpp): a controller tracking a plan on the plant.
#include "refdyn/simulate/closed_loop.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/dual_dynamics.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

namespace refdyn {

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

// The joint system X = [x_ref; x_plant] that Dormand–Prince and BDF integrate: the planner's state
// and the plant's, the reference q̂, q̂̇, q̂̈ taken from the planner at every evaluation.
struct JointSystem {
  JointSystem(const Model& m, const ForceSet& f, Controller& c, Planner& p, const Eigen::VectorXd& limit)
      : plant(m), forces(f), controller(c), planner(p), limit(limit), w(m, f), nr(p.state_size()), xr(nr), dxr(nr),
        data(m) {}
  const Model& plant;
  const ForceSet& forces;
  Controller& controller;
  Planner& planner;
  const Eigen::VectorXd& limit;
  PlantWorkspace w;
  int nr;
  Eigen::VectorXd xr, dxr;

  /// The planner's state and derivative at X, the reference set in w.
  void reference(double t, const Eigen::VectorXd& X) {
    xr = X.head(nr);
    planner.derivative(t, xr, dxr);
    const double *q = nullptr, *qd = nullptr, *qdd = nullptr;
    planner.reference(xr, dxr, q, qd, qdd);
    const int n = plant.nv;
    w.qr = Eigen::Map<const Eigen::VectorXd>(q, n);
    w.qdr = Eigen::Map<const Eigen::VectorXd>(qd, n);
    w.qddr = Eigen::Map<const Eigen::VectorXd>(qdd, n);
  }
  void derivative(double t, const Eigen::VectorXd& X, Eigen::VectorXd& dX) {
    reference(t, X);
    dX.head(nr) = dxr;
    plant_derivative(plant, forces, controller, w, limit, t, X.data() + nr, dX.data() + nr);
  }

  // ∂ẋ/∂x (method bdf). The planner's block is its own Jacobian; the plant's rows come from dual
  // numbers seeded on the plant's state and on the reference (q̂, q̂̇ from x_ref; q̂̈ carries the
  // planner's rows ∂q̂̈/∂x_ref), and M δq̈ = δτ + δQ − δ(M q̈* + c + g) at the solved q̈* (a
  // saturated joint's τ is constant). Evaluates derivative(t, X, ·) first.
  Data data;
  Eigen::VectorXd dX;
  Eigen::MatrixXd Jr, r;
  Eigen::LLT<Eigen::MatrixXd> llt;
  std::vector<JacobianScalar> q, qd, z, xc, qr, qdr, qddr, tau, Q, zdot, xcdot, id;
  void jacobian(double t, const Eigen::VectorXd& X, Eigen::MatrixXd& J) {
    using D = JacobianScalar;
    const int n = plant.nv, nz = forces.num_states(), nc = controller.num_states(), N = static_cast<int>(X.size());
    dX.resize(N);
    derivative(t, X, dX);  // dxr and the plant's q̈ (w.data.ddq) at X
    planner.jacobian(t, X.head(nr), Jr);
    J.setZero(N, N);
    J.topLeftCorner(nr, nr) = Jr;
    for (int i = 0; i < n; ++i) J(nr + i, nr + n + i) = 1.0;
    for (auto* v : {&q, &qd, &qr, &qdr, &qddr, &tau, &Q, &id}) v->resize(n);
    for (auto* v : {&z, &zdot}) v->resize(std::max(nz, 1));
    for (auto* v : {&xc, &xcdot}) v->resize(std::max(nc, 1));
    r.resize(n, N);
    const double* xp = X.data() + nr;
    for (int c0 = 0; c0 < N; c0 += kJacobianDirections) {
      const int cols = std::min(kJacobianDirections, N - c0);
      auto seed = [&](int col, double value) {
        D v(value);
        if (col >= c0 && col < c0 + cols) v.d[col - c0] = 1.0;
        return v;
      };
      for (int i = 0; i < n; ++i) {
        q[i] = seed(nr + i, xp[i]);
        qd[i] = seed(nr + n + i, xp[n + i]);
        qr[i] = seed(i, w.qr[i]);
        qdr[i] = seed(n + i, w.qdr[i]);
        qddr[i] = D(w.qddr[i]);
        for (int k = 0; k < cols; ++k) qddr[i].d[k] = c0 + k < nr ? Jr(n + i, c0 + k) : 0.0;
      }
      for (int k = 0; k < nz; ++k) z[k] = seed(nr + 2 * n + k, xp[2 * n + k]);
      for (int k = 0; k < nc; ++k) xc[k] = seed(nr + 2 * n + nz + k, xp[2 * n + nz + k]);
      controller.compute_dual(t, q.data(), qd.data(), qr.data(), qdr.data(), qddr.data(), xc.data(), tau.data(),
                              nc ? xcdot.data() : nullptr);
      for (int i = 0; i < limit.size(); ++i)
        if (std::abs(tau[i].v) > limit[i]) tau[i] = D(tau[i].v > 0 ? limit[i] : -limit[i]);
      forces.evaluate_dual(t, q.data(), qd.data(), z.data(), n, Q.data(), zdot.data());
      for (int i = 0; i < n; ++i) id[i] = D(w.data.ddq[i]);
      inverse_dynamics_dual(plant, q.data(), qd.data(), id.data(), true, id.data());
      for (int i = 0; i < n; ++i) {
        const D res = tau[i] + Q[i] - id[i];
        for (int k = 0; k < cols; ++k) r(i, c0 + k) = res.d[k];
      }
      for (int k = 0; k < nz; ++k)
        for (int c = 0; c < cols; ++c) J(nr + 2 * n + k, c0 + c) = zdot[k].d[c];
      for (int k = 0; k < nc; ++k)
        for (int c = 0; c < cols; ++c) J(nr + 2 * n + nz + k, c0 + c) = xcdot[k].d[c];
    }
    unchecked::crba(plant, data, Eigen::Map<const Eigen::VectorXd>(xp, n));
    llt.compute(data.M);
    if (llt.info() != Eigen::Success)
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
    J.block(nr + n, 0, n, N) = llt.solve(r);
  }
};

}  // namespace

ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, Planner* rd, const Eigen::VectorXd& x0_plant,
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
    if (!rd)
      throw Error(std::string("simulate_closed_loop: ") + to_string(io.method) +
                  " needs the planner (reference dynamics) to integrate jointly");
    JointSystem sys(plant, plant_forces, controller, *rd, options.effort_limit);
    const int nr = sys.nr;
    auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { sys.derivative(t, x, dx); };
    auto obs = [&](double t, const Eigen::VectorXd& x) {
      sys.reference(t, x);
      w.qr = sys.w.qr, w.qdr = sys.w.qdr, w.qddr = sys.w.qddr;
      record(t, x.data() + nr);
      return true;
    };
    Eigen::VectorXd x(nr + nx);
    x.head(nr) = plan.x.front();
    x.tail(nx) = x0;
    OdeJacobian jacobian;
    if (io.method == IntegratorMethod::BDF)
      jacobian = [&](double t, const Eigen::VectorXd& X, Eigen::MatrixXd& J) { sys.jacobian(t, X, J); };
    OdeProjection projection;  // the planner's part of the state, when its stabilization projects
    Eigen::VectorXd xr_projected(nr);
    if (rd->projects())
      projection = [&](double t, Eigen::VectorXd& X) {
        xr_projected = X.head(nr);
        rd->project(t, xr_projected);
        X.head(nr) = xr_projected;
      };
    out.summary = integrate(rhs, x, io, obs, jacobian, projection);
  }
  out.summary.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

void closed_loop_derivative(const Model& plant, const ForceSet& plant_forces, Controller& controller, Planner& planner,
                            const Eigen::VectorXd& effort_limit, double t, const Eigen::VectorXd& X,
                            Eigen::VectorXd& dX, Eigen::MatrixXd* J) {
  const int N = planner.state_size() + 2 * plant.nv + plant_forces.num_states() + controller.num_states();
  check_vector("closed-loop state X", X, N, "X = [x_ref; q; qd; z_plant; xc]");
  JointSystem sys(plant, plant_forces, controller, planner, effort_limit);
  dX.resize(N);
  sys.derivative(t, X, dX);
  if (J) sys.jacobian(t, X, *J);
}

ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, ReferenceDynamics* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options) {
  if (!rd) return simulate_closed_loop(plant, plant_forces, controller, plan, static_cast<Planner*>(nullptr), x0_plant, options);
  ReferencePlanner planner(*rd);
  return simulate_closed_loop(plant, plant_forces, controller, plan, &planner, x0_plant, options);
}

}  // namespace refdyn
