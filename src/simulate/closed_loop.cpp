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

// The motors' efforts as an applied force of the constrained plant: `tau` is set before every
// evaluation. Under dual numbers it is a constant: the closed loop's Jacobian adds τ's own
// derivatives through ∂q̈/∂τ (ConstrainedPlant::effort_map).
class MotorEfforts final : public ForceElement {
 public:
  explicit MotorEfforts(const Eigen::VectorXd& tau) : tau_(tau) {}
  std::string name() const override { return "motors"; }
  bool actuator() const override { return true; }
  void apply(double, const Eigen::VectorXd&, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
             Eigen::MatrixXd*) const override {
    Q += tau_;
  }
  void apply_dual(double, const JacobianScalar*, const JacobianScalar*, const JacobianScalar*, JacobianScalar* Q,
                  JacobianScalar*) const override {
    for (Eigen::Index i = 0; i < tau_.size(); ++i) Q[i] += tau_[i];
  }

 private:
  const Eigen::VectorXd& tau_;
};

// The plant with its material rows: the planner's machinery over the material rows alone, with
// the plant's forces and the motors' efforts as its applied forces.
struct ConstrainedPlant {
  ConstrainedPlant(const Model& m, const ForceSet& f, const ConstraintSet& material, ReferenceDynamicsOptions o,
                   const Controller& c)
      : tau(Eigen::VectorXd::Zero(m.nv)), forces(f), x(2 * m.nv + f.num_states()), dx(x.size()) {
    forces.add(std::make_shared<MotorEfforts>(tau));
    if (c.actuation().constrained()) {  // the controller's assigned coordinates (else: o's partition)
      o.independent.clear();
      for (int j : c.actuation().independent) o.independent.push_back(m.joint_name[j]);
    }
    o.automatic_partition = true;  // the plant's q̈ does not depend on it: never stop for it
    rd = std::make_unique<ReferenceDynamics>(m, forces, material, o);
  }
  Eigen::VectorXd tau;  // the motors' efforts (MotorEfforts reads it)
  ForceSet forces;
  std::unique_ptr<ReferenceDynamics> rd;
  Eigen::VectorXd x, dx;  // [q; q̇; z_plant]
  /// The last evaluation's inputs (t, [q; q̇; z_plant; xc], q̂, q̂̇, q̂̈) and outputs besides dx and
  /// rd's results (τ, ẋc, saturation): a sample recorded at the end of an RK4 step is the next
  /// step's first stage, evaluated once. Cleared when rd is used for anything else.
  struct Last {
    bool valid = false;
    double t = 0;
    Eigen::VectorXd x, qr, qdr, qddr, tau, xc_dot;
    bool saturated = false;
  } last;
  bool projects() const { return rd->options().stabilization != Stabilization::Baumgarte; }
  /// ∂q̈/∂τ at the last evaluation: G = M⁻¹ − M⁻¹Aᵀ(A M⁻¹ Aᵀ)⁻¹ A M⁻¹ (the KKT solution's
  /// dependence on the applied force; the same for the projection, which solves the same system).
  void effort_map(const Model& m, Data& data, Eigen::MatrixXd& G) const {
    unchecked::crba(m, data, x.head(m.nv));
    Eigen::LLT<Eigen::MatrixXd> llt(data.M);
    if (llt.info() != Eigen::Success) throw NumericalFailure(0, "the plant's mass matrix is not positive definite");
    const Eigen::MatrixXd& A = rd->constraints().A;
    const Eigen::MatrixXd Minv = llt.solve(Eigen::MatrixXd::Identity(m.nv, m.nv));
    const Eigen::MatrixXd Y = Minv * A.transpose();
    Eigen::PartialPivLU<Eigen::MatrixXd> lu(A * Y);
    G = Minv - Y * lu.solve(Y.transpose());
  }
};

struct PlantWorkspace {
  PlantWorkspace(const Model& m, const ForceSet& f, const ClosedLoopOptions& o, const Controller& c)
      : data(m), q(m.nv), qd(m.nv), tau(m.nv), Q(m.nv), zdot(std::max(1, f.num_states())),
        qr(m.nv), qdr(m.nv), qddr(m.nv) {
    if (o.material && o.material->rows() > 0) constrained = std::make_unique<ConstrainedPlant>(m, f, *o.material, o.plant, c);
  }
  Data data;
  Eigen::VectorXd q, qd, tau, Q, zdot, qr, qdr, qddr;
  std::unique_ptr<ConstrainedPlant> constrained;  // null: an unconstrained plant
};

// τ from the controller, saturated; returns true when a joint was saturated. With `dynamics`,
// the plant's M and c + g at this state are in it and the controller may reuse them; with
// `rows`, the plant's material rows (the controller's set) at this state. xc: the
// controller's states, xc_dot: their derivatives (null: not needed).
bool control(Controller& c, PlantWorkspace& w, double t, const Eigen::VectorXd& limit, const Model& plant,
             const Data* dynamics, const PlantRows* rows, const double* xc, double* xc_dot) {
  const ReferenceSample ref{w.qr, w.qdr, w.qddr};
  c.compute(t, w.q, w.qd, ref, xc, xc_dot, w.tau, &plant, dynamics, rows);
  bool sat = false;
  for (int i = 0; i < limit.size(); ++i) {
    if (w.tau[i] > limit[i]) w.tau[i] = limit[i], sat = true;
    if (w.tau[i] < -limit[i]) w.tau[i] = -limit[i], sat = true;
  }
  return sat;
}

// The constrained plant at (t, x), x = [q; q̇; z_plant; xc] (q, q̇ already in w): M, c + g and the
// material rows evaluated once, the controller's τ from them (same model, same rows), then the
// plant's q̈, λ and Q_c with that τ; the plant's ẋ in w.constrained->dx. Returns true when a
// joint was saturated.
bool constrained_derivative(const Model& m, Controller& c, PlantWorkspace& w, const Eigen::VectorXd& limit, double t,
                            const double* x, double* xc_dot) {
  ConstrainedPlant& p = *w.constrained;
  const int n = m.nv, nz = static_cast<int>(p.x.size()) - 2 * n, nc = c.num_states();
  const Eigen::Map<const Eigen::VectorXd> xs(x, 2 * n + nz + nc);
  ConstrainedPlant::Last& last = p.last;
  auto same = [](const Eigen::VectorXd& a, const double* b) { return std::equal(a.data(), a.data() + a.size(), b); };
  if (last.valid && last.t == t && same(last.x, x) && same(last.qr, w.qr.data()) && same(last.qdr, w.qdr.data()) &&
      same(last.qddr, w.qddr.data())) {
    w.tau = last.tau;  // p.dx and rd's results are this evaluation's
    if (xc_dot) Eigen::Map<Eigen::VectorXd>(xc_dot, nc) = last.xc_dot;
    return last.saturated;
  }
  p.x = xs.head(2 * n + nz);
  ReferenceDynamics& rd = *p.rd;
  rd.prepare_derivative(t, p.x, p.dx);
  PlantRows rows;  // the plant's rows and factored partition, when they are the controller's
  if (c.actuation().material.get() == &rd.constraint_set()) {
    rows.rows = &rd.constraints();
    if (rd.partition_factored())
      rows.independent = &rd.independent(), rows.dependent = &rd.dependent(), rows.Kinv = &rd.partition_inverse(),
      rows.G = &rd.partition_g();
  }
  last.xc_dot.resize(nc);
  const bool sat = control(c, w, t, limit, m, rd.mass_filled() ? &rd.data() : nullptr, rows.rows ? &rows : nullptr,
                           nc ? x + 2 * n + nz : nullptr, nc ? last.xc_dot.data() : nullptr);
  if (xc_dot) Eigen::Map<Eigen::VectorXd>(xc_dot, nc) = last.xc_dot;
  p.tau = w.tau;
  rd.complete_derivative(t, p.x, p.dx);
  last.valid = true, last.t = t, last.x = xs, last.qr = w.qr, last.qdr = w.qdr, last.qddr = w.qddr;
  last.tau = w.tau, last.saturated = sat;
  return sat;
}

// Plant ẋ from (t, x), x = [q; q̇; z_plant; xc], with the reference already in w.qr/qdr/qddr.
void plant_derivative(const Model& m, const ForceSet& forces, Controller& c, PlantWorkspace& w,
                      const Eigen::VectorXd& limit, double t, const double* x, double* dx) {
  const int n = m.nv, nz = forces.num_states(), nc = c.num_states();
  w.q = Eigen::Map<const Eigen::VectorXd>(x, n);
  w.qd = Eigen::Map<const Eigen::VectorXd>(x + n, n);
  if (w.constrained) {  // the material rows' reactions join: the planner's machinery solves
    constrained_derivative(m, c, w, limit, t, x, nc ? dx + 2 * n + nz : nullptr);
    Eigen::Map<Eigen::VectorXd>(dx, 2 * n + nz) = w.constrained->dx;
    return;
  }
  if (forward_dynamics_uses_aba(n) && !c.reuses_dynamics(m)) {  // articulated-body algorithm: no M needed
    control(c, w, t, limit, m, nullptr, nullptr, nc ? x + 2 * n + nz : nullptr, nc ? dx + 2 * n + nz : nullptr);
    forces.evaluate(t, w.q, w.qd, nz ? x + 2 * n : nullptr, w.Q, w.zdot.data());
    w.Q += w.tau;
    if (unchecked::aba(m, w.data, w.q, w.qd, w.Q, w.data.ddq) >= 0)
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
  } else {  // the controller reuses M and c + g: CRBA + Cholesky
    unchecked::mass_matrix_and_bias(m, w.data, w.q, w.qd);
    control(c, w, t, limit, m, &w.data, nullptr, nc ? x + 2 * n + nz : nullptr, nc ? dx + 2 * n + nz : nullptr);
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
  JointSystem(const Model& m, const ForceSet& f, Controller& c, Planner& p, const ClosedLoopOptions& o)
      : plant(m), forces(f), controller(c), planner(p), limit(o.effort_limit), w(m, f, o, c), nr(p.state_size()),
        xr(nr), dxr(nr), data(m) {}
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
  // With material rows the plant's rows are its own exact Jacobian at fixed τ (the planner's
  // machinery, ReferenceDynamics::jacobian) plus ∂q̈/∂τ · ∂τ/∂X, τ's row T from the controller's
  // law over dual numbers.
  Data data;
  Eigen::VectorXd dX;
  Eigen::MatrixXd Jr, r, Jp, T, G;
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
      for (int k = 0; k < nc; ++k)
        for (int c = 0; c < cols; ++c) J(nr + 2 * n + nz + k, c0 + c) = xcdot[k].d[c];
      if (w.constrained) {
        T.resize(n, N);
        for (int i = 0; i < n; ++i)
          for (int k = 0; k < cols; ++k) T(i, c0 + k) = tau[i].d[k];
        continue;
      }
      forces.evaluate_dual(t, q.data(), qd.data(), z.data(), n, Q.data(), zdot.data());
      for (int i = 0; i < n; ++i) id[i] = D(w.data.ddq[i]);
      inverse_dynamics_dual(plant, q.data(), qd.data(), id.data(), true, id.data());
      for (int i = 0; i < n; ++i) {
        const D res = tau[i] + Q[i] - id[i];
        for (int k = 0; k < cols; ++k) r(i, c0 + k) = res.d[k];
      }
      for (int k = 0; k < nz; ++k)
        for (int c = 0; c < cols; ++c) J(nr + 2 * n + k, c0 + c) = zdot[k].d[c];
    }
    if (w.constrained) {
      ConstrainedPlant& p = *w.constrained;  // p.x and p.tau hold X's plant state and τ
      p.rd->jacobian(t, p.x, Jp);
      p.last.valid = false;  // rd's workspaces now hold the Jacobian's evaluations
      J.block(nr, nr, 2 * n + nz, 2 * n + nz) = Jp;
      p.effort_map(plant, data, G);
      J.block(nr + n, 0, n, N) += G * T;
      return;
    }
    unchecked::crba(plant, data, Eigen::Map<const Eigen::VectorXd>(xp, n));
    llt.compute(data.M);
    if (llt.info() != Eigen::Success)
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the plant's mass matrix is not positive definite");
    J.block(nr + n, 0, n, N) = llt.solve(r);
  }
};

// The arguments of simulate_closed_loop checked: sizes, finite values, limits, points, orders.
void check_closed_loop_inputs(const Model& plant, int nx, int nz, const Plan& plan, const Eigen::VectorXd& x0_plant,
                              const ClosedLoopOptions& options) {
  const int n = plant.nv;
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
  if (options.material)
    for (const ConstraintPtr& c : options.material->constraints())
      if (c->order() > 1)
        throw Error("simulate_closed_loop: the plant's constraint '" + c->name + "' is of acceleration level; a "
                    "material constraint is holonomic or first order");
}

// One closed-loop run: the plant's workspace, what is recorded at each sample, and the two ways
// of integrating it (replay_rk4: the plan's recorded RK4 stages; integrate_jointly: the planner
// integrated with the plant, for Dormand–Prince and BDF).
class ClosedLoopRun {
 public:
  ClosedLoopRun(const Model& plant, const ForceSet& forces, Controller& controller, const Plan& plan,
                const ClosedLoopOptions& options)
      : plant_(plant), forces_(forces), controller_(controller), plan_(plan), options_(options),
        n_(plant.nv), nz_(forces.num_states()), nc_(controller.num_states()), nx_(2 * n_ + nz_ + nc_),
        w_(plant, forces, options, controller), kin_(plant) {}

  int state_size() const { return nx_; }

  /// The result's names: joints, states, points, material rows.
  void start(ClosedLoopResult& out) const {
    out.joints = plant_.joint_name;
    out.state_names = forces_.state_names();
    for (const auto& s : controller_.state_names()) out.state_names.push_back(s);
    for (int p : options_.points) out.points.push_back(plant_.point_name[p]);
    if (w_.constrained) {
      const ConstraintSet& mat = *options_.material;
      for (int r = 0; r < mat.rows(); ++r) out.constraint_rows.push_back(mat.row_name(r)), out.material_row.push_back(1);
    }
  }

  /// The plan's RK4 stages replayed on the same grid (the reference at every stage is the plan's).
  IntegrationSummary replay_rk4(const Eigen::VectorXd& x0, ClosedLoopResult& out) {
    const IntegratorOptions& io = options_.integrator;
    const int n = n_;
    const ReferenceStages& st = plan_.stages;
    if (st.steps == 0 || st.n != n)
      throw Error("simulate_closed_loop: the plan has no recorded RK4 stages for this plant (hint: plan with RK4)");
    const Rk4Grid grid(io);
    const long nsteps = grid.steps();
    const double h = grid.uniform() ? grid.uniform_step() : (io.t1 - io.t0) / static_cast<double>(nsteps);
    if (std::abs(io.t0 - st.t0) > 1e-12 || std::abs(h - st.h) > 1e-12 * st.h || io.breakpoints != st.breakpoints)
      throw Error(expected_got("closed-loop RK4 grid", "t0 = " + fmt(st.t0) + " and step = " + fmt(st.h) + " (the plan's)",
                               "t0 = " + fmt(io.t0) + ", step = " + fmt(h) +
                                   (io.breakpoints != st.breakpoints ? " on other breakpoints" : "")));
    // Samples beyond the recorded stages use the plan's samples (only the final time).
    long usable = std::min<long>(nsteps, st.steps);
    // On a grid with breakpoints a shorter run ends on one (its grid is then the same up to there).
    while (!grid.uniform() && usable < nsteps && usable > 0 && grid.part(usable) == grid.part(usable - 1)) --usable;
    IntegratorOptions o = io;
    o.t1 = grid.uniform() ? io.t0 + usable * h : usable > 0 ? grid.end(usable - 1) : io.t0;
    // The stage hook says which recorded reference stage belongs to this evaluation.
    auto rhs = [&](const Stage& stage, double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
      const double* s = st.stage(stage.step, stage.stage);
      set_reference(s, s + n, s + 2 * n);
      plant_derivative(plant_, forces_, controller_, w_, options_.effort_limit, t, x.data(), dx.data());
    };
    const long every = io.output_interval > 0 ? std::max(1L, std::lround(io.output_interval / h)) : 1L;
    // The steps whose ends are output samples (the plan's grid, Rk4Grid), after t0's (step 0).
    std::vector<long> sample_step{0};
    for (long k = 0; !grid.uniform() && k < nsteps; ++k)
      if (grid.sample(k)) sample_step.push_back(k + 1);
    reserve(out, grid.uniform() ? static_cast<size_t>(usable / every + 2) : sample_step.size() + 1);
    long sample = 0;
    auto obs = [&](double t, const Eigen::VectorXd& x) {
      const long step = grid.uniform() ? sample * every
                        : static_cast<size_t>(sample) < sample_step.size() ? sample_step[static_cast<size_t>(sample)]
                                                                            : st.steps;
      ++sample;
      if (step < st.steps) {
        const double* s = st.stage(step, 0);
        set_reference(s, s + n, s + 2 * n);
      } else {  // the plan's last sample
        const Eigen::VectorXd& xr = plan_.x.back();
        set_reference(xr.data(), xr.data() + n, plan_.qdd.back().data());
      }
      record(t, x.data(), out);
      return true;
    };
    Eigen::VectorXd x = x0;
    OdeProjection projection;
    if (plant_projects()) projection = [&](double t, Eigen::VectorXd& X) { project_plant(t, X.data()); };
    IntegrationSummary summary = integrate_staged(rhs, x, o, obs, {}, projection);
    if (summary.ok() && usable < nsteps) {
      summary.status = IntegrationStatus::Stopped;
      summary.message = "the plan ends at t = " + fmt(o.t1) + " s, before the requested t1 = " + fmt(io.t1) + " s";
    }
    return summary;
  }

  /// The planner and the plant integrated together (X = [x_ref; x_plant]), the reference taken
  /// from the planner at every evaluation.
  IntegrationSummary integrate_jointly(Planner& rd, const Eigen::VectorXd& x0, ClosedLoopResult& out) {
    const IntegratorOptions& io = options_.integrator;
    JointSystem sys(plant_, forces_, controller_, rd, options_);
    const int nr = sys.nr;
    auto rhs = [&](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { sys.derivative(t, x, dx); };
    auto obs = [&](double t, const Eigen::VectorXd& x) {
      sys.reference(t, x);
      w_.qr = sys.w.qr, w_.qdr = sys.w.qdr, w_.qddr = sys.w.qddr;
      record(t, x.data() + nr, out);
      return true;
    };
    Eigen::VectorXd x(nr + nx_);
    x.head(nr) = plan_.x.front();
    x.tail(nx_) = x0;
    OdeJacobian jacobian;
    if (io.method == IntegratorMethod::BDF)
      jacobian = [&](double t, const Eigen::VectorXd& X, Eigen::MatrixXd& J) { sys.jacobian(t, X, J); };
    OdeProjection projection;  // the planner's part of the state, when its stabilization projects, and the plant's
    Eigen::VectorXd xr_projected(nr);
    const bool plant_proj = plant_projects();
    if (rd.projects() || plant_proj)
      projection = [&](double t, Eigen::VectorXd& X) {
        if (rd.projects()) {
          xr_projected = X.head(nr);
          rd.project(t, xr_projected);
          X.head(nr) = xr_projected;
        }
        if (plant_proj) project_plant(t, X.data() + nr);
      };
    return integrate(rhs, x, io, obs, jacobian, projection);
  }

 private:
  void set_reference(const double* q, const double* qd, const double* qdd) {
    w_.qr = Eigen::Map<const Eigen::VectorXd>(q, n_);
    w_.qdr = Eigen::Map<const Eigen::VectorXd>(qd, n_);
    w_.qddr = Eigen::Map<const Eigen::VectorXd>(qdd, n_);
  }

  /// Room for `samples` samples in every per-sample field that record() fills.
  void reserve(ClosedLoopResult& out, size_t samples) const {
    out.t.reserve(samples);
    for (auto* v : {&out.x, &out.tau, &out.q_ref, &out.qd_ref, &out.point_positions}) v->reserve(samples);
    if (w_.constrained)
      for (auto* v : {&out.phi, &out.phid, &out.lambda, &out.reaction_effort}) v->reserve(samples);
  }

  /// One sample: the state, τ (saturations counted), the reference, points, and with material
  /// rows their residuals and reactions.
  void record(double t, const double* xp, ClosedLoopResult& out) {
    const int n = n_, nz = nz_;
    out.t.push_back(t);
    out.x.push_back(Eigen::Map<const Eigen::VectorXd>(xp, nx_));
    w_.q = Eigen::Map<const Eigen::VectorXd>(xp, n);
    w_.qd = Eigen::Map<const Eigen::VectorXd>(xp + n, n);
    const bool saturated =
        w_.constrained ? constrained_derivative(plant_, controller_, w_, options_.effort_limit, t, xp, nullptr)
                       : control(controller_, w_, t, options_.effort_limit, plant_, nullptr, nullptr,
                                 nc_ ? xp + 2 * n + nz : nullptr, nullptr);
    if (saturated) ++out.saturated_samples;
    out.tau.push_back(w_.tau);
    out.q_ref.push_back(w_.qr);
    out.qd_ref.push_back(w_.qdr);
    pts_.resize(3 * static_cast<Eigen::Index>(options_.points.size()));
    if (!options_.points.empty()) {
      forward_kinematics(plant_, kin_, w_.q);
      for (size_t k = 0; k < options_.points.size(); ++k)
        pts_.segment<3>(3 * k) = point_position(plant_, kin_, options_.points[k]);
    }
    out.point_positions.push_back(pts_);
    if (w_.constrained) {  // the material rows and their reactions at this sample
      const ConstrainedPlant& p = *w_.constrained;
      const ConstraintEval& ev = p.rd->constraints();
      out.phi.push_back(ev.phi);
      out.phid.push_back(ev.phid);
      out.lambda.push_back(p.rd->lambda());
      out.reaction_effort.push_back(p.rd->constraint_force());
      if (ev.phi.size()) out.max_material_residual = std::max(out.max_material_residual, ev.phi.cwiseAbs().maxCoeff());
    }
    if (options_.progress) options_.progress(t);
  }

  /// Stabilisation by projection of the plant's material rows (plant.stabilization): after each step.
  bool plant_projects() const { return w_.constrained && w_.constrained->projects(); }
  void project_plant(double t, double* xp) {
    ConstrainedPlant& p = *w_.constrained;
    p.last.valid = false;  // rd evaluates other states
    const int m = 2 * n_ + nz_;
    xp_projected_ = Eigen::Map<const Eigen::VectorXd>(xp, m);
    p.rd->project_state(t, xp_projected_);
    Eigen::Map<Eigen::VectorXd>(xp, m) = xp_projected_;
  }

  const Model& plant_;
  const ForceSet& forces_;
  Controller& controller_;
  const Plan& plan_;
  const ClosedLoopOptions& options_;
  int n_, nz_, nc_, nx_;
  PlantWorkspace w_;
  Data kin_;
  Eigen::VectorXd xp_projected_, pts_;  // workspaces (pts_: the recorded points of a sample)
};

}  // namespace

ClosedLoopResult simulate_closed_loop(const Model& plant, const ForceSet& plant_forces, Controller& controller,
                                      const Plan& plan, Planner* rd, const Eigen::VectorXd& x0_plant,
                                      const ClosedLoopOptions& options) {
  const IntegratorOptions& io = options.integrator;
  io.validate();
  const int n = plant.nv, nz = plant_forces.num_states(), nx = 2 * n + nz + controller.num_states();
  check_closed_loop_inputs(plant, nx, nz, plan, x0_plant, options);
  ClosedLoopResult out;
  ClosedLoopRun run(plant, plant_forces, controller, plan, options);
  run.start(out);
  const auto start = std::chrono::steady_clock::now();
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(nx);
  x0.head(x0_plant.size()) = x0_plant;
  if (replays_stages(io.method)) {
    out.summary = run.replay_rk4(x0, out);
  } else {
    if (!rd)
      throw Error(std::string("simulate_closed_loop: ") + to_string(io.method) +
                  " needs the planner (reference dynamics) to integrate jointly");
    out.summary = run.integrate_jointly(*rd, x0, out);
  }
  out.summary.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

void closed_loop_derivative(const Model& plant, const ForceSet& plant_forces, Controller& controller, Planner& planner,
                            const Eigen::VectorXd& effort_limit, double t, const Eigen::VectorXd& X,
                            Eigen::VectorXd& dX, Eigen::MatrixXd* J) {
  ClosedLoopOptions o;
  o.effort_limit = effort_limit;
  closed_loop_derivative(plant, plant_forces, controller, planner, o, t, X, dX, J);
}

void closed_loop_derivative(const Model& plant, const ForceSet& plant_forces, Controller& controller, Planner& planner,
                            const ClosedLoopOptions& options, double t, const Eigen::VectorXd& X, Eigen::VectorXd& dX,
                            Eigen::MatrixXd* J) {
  const int N = planner.state_size() + 2 * plant.nv + plant_forces.num_states() + controller.num_states();
  check_vector("closed-loop state X", X, N, "X = [x_ref; q; qd; z_plant; xc]");
  JointSystem sys(plant, plant_forces, controller, planner, options);
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
