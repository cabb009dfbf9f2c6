// Tracking: analytic closed-loop solutions, the exact-reference property, saturation, and the
// feasibility report.
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/planner.hpp"
#include "refdyn/simulate/feasibility.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/models/paper_study.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <cmath>
#include <numbers>
#include <random>

using namespace refdyn;
using refdyn::test::near;

namespace {

struct Fixture {
  models::PaperExample ex;
  ReferenceDynamics rd{ex.model, ex.forces, ex.constraints, ex.options()};
  Plan plan = plan_motion(rd, rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), {ex.integrator(), 0.5});
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

Eigen::VectorXd plant_start(double alpha0_deg, int nz = 0) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(6 + nz);
  x[1] = 1.5 * std::numbers::pi - alpha0_deg * std::numbers::pi / 180.0;
  x[2] = 0.5;
  return x;
}

}  // namespace

TEST(Control, PerfectModelErrorIsCriticallyDampedClosedForm) {
  Fixture& f = fixture();
  ASSERT_TRUE(f.plan.summary.ok()) << f.plan.summary.message;
  const Eigen::Vector3d delta(40, 3, 60);
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  const ForceSet none;
  for (double a0 : {45.0, 60.0, 70.0, 80.0}) {
    ComputedTorquePD ctrl(f.ex.model, delta);
    const ClosedLoopResult r = simulate_closed_loop(f.ex.model, none, ctrl, f.plan, nullptr, plant_start(a0), o);
    ASSERT_TRUE(r.summary.ok()) << r.summary.message;
    ASSERT_EQ(r.t.size(), f.plan.t.size());
    double worst = 0;
    for (int j = 0; j < 3; ++j) {
      const double e0 = r.x[0][j] - r.q_ref[0][j];
      for (size_t k = 0; k < r.t.size(); ++k) {
        const double t = r.t[k];
        const double e = r.x[k][j] - r.q_ref[k][j];
        const double expected = e0 * (1 + delta[j] * t) * std::exp(-delta[j] * t);
        worst = std::max(worst, std::abs(e - expected));
      }
    }
    EXPECT_LT(worst, 1e-8) << "alpha0 = " << a0;
  }
}

// The closed loop computes the plant's M and c + g first and hands them to the controller;
// ComputedTorquePD uses them only when they belong to its own model (same Model object).
TEST(Control, ComputedTorqueReusesThePlantDynamicsOnlyForItsOwnModel) {
  Fixture& f = fixture();
  const Eigen::Vector3d delta(40, 3, 60);
  ComputedTorquePD ctrl(f.ex.model, delta);
  std::mt19937 rng(71);
  const Eigen::VectorXd q = test::random_vector(rng, 3, 2.0), qd = test::random_vector(rng, 3, 1.0);
  const Eigen::VectorXd qr = test::random_vector(rng, 3, 2.0), qdr = test::random_vector(rng, 3, 1.0),
                        qddr = test::random_vector(rng, 3, 1.0);
  const ReferenceSample ref{qr, qdr, qddr};
  Eigen::VectorXd tau(3), tau_reused(3);
  ctrl.compute(0.0, q, qd, ref, tau);
  Data d(f.ex.model);
  unchecked::mass_matrix_and_bias(f.ex.model, d, q, qd);
  ctrl.compute(0.0, q, qd, ref, nullptr, nullptr, tau_reused, &f.ex.model, &d);
  EXPECT_TRUE(near(tau_reused, tau, 1e-14, 1e-14));
  // Proof that the given dynamics are really used for the own model ...
  d.M *= 2.0;
  d.nle.setZero();
  ctrl.compute(0.0, q, qd, ref, nullptr, nullptr, tau_reused, &f.ex.model, &d);
  EXPECT_GT((tau_reused - tau).norm(), 1e-3 * tau.norm());
  // ... and ignored for another model object, even an equal one.
  const Model copy = f.ex.model;
  ctrl.compute(0.0, q, qd, ref, nullptr, nullptr, tau_reused, &copy, &d);
  EXPECT_TRUE(near(tau_reused, tau, 0, 0));
  // Whole closed loops: controller on the plant's own model (reuse) vs on a copy (recompute).
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  const ForceSet none;
  ComputedTorquePD own(f.ex.model, delta), other(copy, delta);
  const ClosedLoopResult a = simulate_closed_loop(f.ex.model, none, own, f.plan, nullptr, plant_start(70), o);
  const ClosedLoopResult b = simulate_closed_loop(f.ex.model, none, other, f.plan, nullptr, plant_start(70), o);
  ASSERT_TRUE(a.summary.ok() && b.summary.ok());
  ASSERT_EQ(a.x.size(), b.x.size());
  for (size_t k = 0; k < a.x.size(); ++k) ASSERT_TRUE(near(a.x[k], b.x[k], 1e-12, 1e-12)) << "sample " << k;
}

// A plant whose controller does not reuse M and c + g takes the articulated-body algorithm
// (from kAbaFrom coordinates); one that does, CRBA + Cholesky. The same PD + g controller,
// once declaring reuse and once not, gives the same closed loop by the two routes.
namespace {
class PdGravityDeclaringReuse final : public Controller {
 public:
  PdGravityDeclaringReuse(const Model& model, bool reuse) : pd_(model, kp(), kd()), reuse_(reuse) {}
  static Eigen::VectorXd kp() { return Eigen::Vector3d(400, 40, 900); }
  static Eigen::VectorXd kd() { return Eigen::Vector3d(40, 4, 60); }
  std::string name() const override { return "pd_test"; }
  void compute(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const ReferenceSample& ref,
               const double* xc, double* xc_dot, Eigen::VectorXd& tau, const Model*, const Data*,
               const PlantRows*) override {
    pd_.compute(t, q, qd, ref, xc, xc_dot, tau);
  }
  void compute_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* q_ref,
                    const JacobianScalar* qd_ref, const JacobianScalar* qdd_ref, const JacobianScalar* xc,
                    JacobianScalar* tau, JacobianScalar* xc_dot) const override {
    pd_.compute_dual(t, q, qd, q_ref, qd_ref, qdd_ref, xc, tau, xc_dot);
  }
  const Actuation& actuation() const override { return pd_.actuation(); }
  bool reuses_dynamics(const Model&) const override { return reuse_; }

 private:
  PDGravity pd_;
  bool reuse_;
};
}  // namespace

TEST(Control, PlantTakesTheArticulatedBodyAlgorithmWhenTheControllerDoesNotReuseItsDynamics) {
  Fixture& f = fixture();
  const Model copy = f.ex.model;
  const Eigen::Vector3d delta(40, 3, 60);
  ComputedTorquePD own(f.ex.model, delta), other(copy, delta);
  PDGravity pd(f.ex.model, PdGravityDeclaringReuse::kp(), PdGravityDeclaringReuse::kd());
  EXPECT_TRUE(own.reuses_dynamics(f.ex.model));
  EXPECT_FALSE(other.reuses_dynamics(f.ex.model));
  EXPECT_FALSE(pd.reuses_dynamics(f.ex.model));
  ASSERT_TRUE(forward_dynamics_uses_aba(f.ex.model.nq));
  const ForceSet none;
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  o.integrator.t1 = 2.0;
  PdGravityDeclaringReuse aba(f.ex.model, false), crba(f.ex.model, true);
  const ClosedLoopResult a = simulate_closed_loop(f.ex.model, none, aba, f.plan, nullptr, plant_start(70), o);
  const ClosedLoopResult b = simulate_closed_loop(f.ex.model, none, crba, f.plan, nullptr, plant_start(70), o);
  ASSERT_TRUE(a.summary.ok() && b.summary.ok());
  ASSERT_EQ(a.x.size(), b.x.size());
  for (size_t k = 0; k < a.x.size(); ++k) ASSERT_TRUE(near(a.x[k], b.x[k], 1e-11, 1e-12)) << "sample " << k;
}

TEST(Control, ExactStartTracksToRoundoffAndTorqueEqualsPlanForces) {
  Fixture& f = fixture();
  ComputedTorquePD ctrl(f.ex.model, Eigen::Vector3d(40, 3, 60));
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  const ForceSet none;
  const ClosedLoopResult r = simulate_closed_loop(f.ex.model, none, ctrl, f.plan, nullptr, plant_start(45), o);
  ASSERT_TRUE(r.summary.ok());
  double worst_e = 0, worst_tau = 0;
  Eigen::VectorXd dx(f.rd.state_size());
  for (size_t k = 0; k < r.t.size(); k += 7) {
    worst_e = std::max(worst_e, (r.x[k].head(3) - r.q_ref[k]).cwiseAbs().maxCoeff());
    // The plan's forces: drive + friction (applied_force) + constraint forces.
    f.rd.derivative(f.plan.t[k], f.plan.x[k], dx);
    const Eigen::VectorXd plan_tau = f.rd.applied_force() + f.rd.constraint_force();
    worst_tau = std::max(worst_tau, (r.tau[k] - plan_tau).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst_e, 1e-10);
  EXPECT_LT(worst_tau, 1e-8);
}

TEST(Control, ReplayedStagesEqualJointIntegration) {
  // Integrate [reference; plant] jointly with RK4 by hand and compare with the stage replay.
  Fixture& f = fixture();
  const Eigen::Vector3d delta(40, 3, 60);
  const ForceSet none;
  IntegratorOptions io = f.ex.integrator();
  io.t1 = 1.0;
  ComputedTorquePD c1(f.ex.model, delta), c2(f.ex.model, delta);
  ClosedLoopOptions o;
  o.integrator = io;
  const ClosedLoopResult replay = simulate_closed_loop(f.ex.model, none, c1, f.plan, nullptr, plant_start(70), o);
  ASSERT_TRUE(replay.summary.ok());

  ReferenceDynamics rd(f.ex.model, f.ex.forces, f.ex.constraints, f.ex.options());
  Data data(f.ex.model);
  const int nr = rd.state_size();
  Eigen::VectorXd x(nr + 6), dxr(nr), tau(3);
  x.head(nr) = f.plan.x.front();
  x.tail(6) = plant_start(70);
  auto rhs = [&](double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) {
    rd.derivative(t, xx.head(nr), dxr);
    dx.head(nr) = dxr;
    const Eigen::VectorXd q = xx.segment(nr, 3), qd = xx.segment(nr + 3, 3);
    const Eigen::VectorXd qr = xx.head(3), qdr = xx.segment(3, 3), qddr = dxr.segment(3, 3);
    c2.compute(t, q, qd, ReferenceSample{qr, qdr, qddr}, tau);
    dx.segment(nr, 3) = qd;
    dx.segment(nr + 3, 3) = forward_dynamics(f.ex.model, data, q, qd, tau);
  };
  const IntegrationSummary s = integrate(rhs, x, io);
  ASSERT_TRUE(s.ok());
  EXPECT_TRUE(near(x.tail(6), replay.x.back(), 1e-12, 1e-14));
}

TEST(Control, DormandPrinceJointIntegrationAgreesWithRk4) {
  Fixture& f = fixture();
  const ForceSet none;
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  o.integrator.t1 = 1.0;
  ComputedTorquePD c1(f.ex.model, Eigen::Vector3d(40, 3, 60));
  const ClosedLoopResult rk = simulate_closed_loop(f.ex.model, none, c1, f.plan, nullptr, plant_start(60), o);
  o.integrator.method = IntegratorMethod::DormandPrince45;
  o.integrator.output_interval = 0.1;
  o.integrator.rtol = 1e-10;
  o.integrator.atol = 1e-12;
  ComputedTorquePD c2(f.ex.model, Eigen::Vector3d(40, 3, 60));
  ReferenceDynamics rd(f.ex.model, f.ex.forces, f.ex.constraints, f.ex.options());
  const ClosedLoopResult dp = simulate_closed_loop(f.ex.model, none, c2, f.plan, &rd, plant_start(60), o);
  ASSERT_TRUE(dp.summary.ok()) << dp.summary.message;
  ASSERT_NEAR(dp.t.back(), 1.0, 1e-12);
  EXPECT_TRUE(near(dp.x.back(), rk.x.back(), 1e-7, 1e-9));
  EXPECT_TRUE(near(dp.q_ref.back(), rk.q_ref.back(), 1e-7, 1e-9));
}

// The closed loop's exact Jacobian (implicit integration) against central differences of its
// derivative, for each controller, with plant friction (bristle states), a PID's integral states
// and a saturated joint; X = [x_ref; q; q̇; z_plant; xc].
TEST(Control, ClosedLoopJacobianMatchesFiniteDifferences) {
  Fixture& f = fixture();
  models::PaperExampleParams stiff;
  stiff.lugre_rot.sigma0 = stiff.lugre_lin.sigma0 = 1e4;
  stiff.lugre_rot.sigma1 = stiff.lugre_lin.sigma1 = 50;
  models::PaperExample plant_ex(stiff);  // its forces: drive + stiff LuGre (3 states)
  ReferencePlanner planner(f.rd);
  PIDGravity pid(f.ex.model, Eigen::Vector3d(400, 300, 900), Eigen::Vector3d(50, 40, 30), Eigen::Vector3d(40, 30, 60));
  PDGravity pd(f.ex.model, Eigen::Vector3d(400, 300, 900), Eigen::Vector3d(40, 30, 60));
  ComputedTorquePD ct(f.ex.model, Eigen::Vector3d(40, 3, 60));
  const std::vector<std::pair<Controller*, Eigen::VectorXd>> cases = {
      {&ct, Eigen::VectorXd()}, {&pd, Eigen::VectorXd()}, {&pid, Eigen::VectorXd()}, {&ct, Eigen::Vector3d(1e3, 1e3, 5.0)}};
  std::mt19937 rng(11);
  for (const auto& [c, limit] : cases) {
    const int nr = planner.state_size(), nz = plant_ex.forces.num_states(), nc = c->num_states();
    Eigen::VectorXd X(nr + 6 + nz + nc);
    X.head(nr) = f.plan.x[300];
    X.segment(nr, 6) = f.plan.x[300].head(6) + test::random_vector(rng, 6, 0.05);
    X.segment(nr + 6, nz) = test::random_vector(rng, nz, 1e-5);
    X.tail(nc) = test::random_vector(rng, nc, 0.01);
    const double t = f.plan.t[300];
    Eigen::VectorXd dX;
    Eigen::MatrixXd J;
    closed_loop_derivative(f.ex.model, plant_ex.forces, *c, planner, limit, t, X, dX, &J);
    Eigen::MatrixXd Jfd(X.size(), X.size());
    Eigen::VectorXd Xp = X, fp, fm;
    for (Eigen::Index j = 0; j < X.size(); ++j) {
      const double h = 1e-6 * std::max(1.0, std::abs(X[j]));
      Xp[j] = X[j] + h;
      closed_loop_derivative(f.ex.model, plant_ex.forces, *c, planner, limit, t, Xp, fp);
      Xp[j] = X[j] - h;
      closed_loop_derivative(f.ex.model, plant_ex.forces, *c, planner, limit, t, Xp, fm);
      Xp[j] = X[j];
      Jfd.col(j) = (fp - fm) / (2 * h);
    }
    const double scale = std::max(1.0, Jfd.cwiseAbs().maxCoeff());
    EXPECT_LE((J - Jfd).cwiseAbs().maxCoeff(), 1e-7 * scale) << c->name() << (limit.size() ? " saturated" : "");
  }
}

// BDF on the joint system gives the Dormand–Prince closed loop (both tight).
TEST(Control, BdfJointIntegrationAgreesWithDormandPrince) {
  Fixture& f = fixture();
  const ForceSet none;
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  o.integrator.t1 = 1.0;
  o.integrator.output_interval = 0.1;
  o.integrator.rtol = 1e-10;
  o.integrator.atol = 1e-12;
  o.integrator.method = IntegratorMethod::DormandPrince45;
  ComputedTorquePD c1(f.ex.model, Eigen::Vector3d(40, 3, 60));
  ReferenceDynamics rd1(f.ex.model, f.ex.forces, f.ex.constraints, f.ex.options());
  const ClosedLoopResult dp = simulate_closed_loop(f.ex.model, none, c1, f.plan, &rd1, plant_start(60), o);
  o.integrator.method = IntegratorMethod::BDF;
  ComputedTorquePD c2(f.ex.model, Eigen::Vector3d(40, 3, 60));
  ReferenceDynamics rd2(f.ex.model, f.ex.forces, f.ex.constraints, f.ex.options());
  const ClosedLoopResult bdf = simulate_closed_loop(f.ex.model, none, c2, f.plan, &rd2, plant_start(60), o);
  ASSERT_TRUE(dp.summary.ok()) << dp.summary.message;
  ASSERT_TRUE(bdf.summary.ok()) << bdf.summary.message;
  ASSERT_EQ(bdf.t.size(), dp.t.size());
  EXPECT_TRUE(near(bdf.x.back(), dp.x.back(), 1e-6, 1e-8));
  EXPECT_GT(bdf.summary.jacobian_evaluations, 0);
}

TEST(Control, SaturationIsRespected) {
  Fixture& f = fixture();
  const ForceSet none;
  ClosedLoopOptions o;
  o.integrator = f.ex.integrator();
  o.integrator.t1 = 1.0;
  o.effort_limit = Eigen::Vector3d(0.5, 9.0, 24.0);
  ComputedTorquePD c(f.ex.model, Eigen::Vector3d(40, 3, 60));
  const ClosedLoopResult r = simulate_closed_loop(f.ex.model, none, c, f.plan, nullptr, plant_start(80), o);
  ASSERT_TRUE(r.summary.ok());
  EXPECT_GT(r.saturated_samples, 0);
  for (const auto& tau : r.tau)
    for (int j = 0; j < 3; ++j) EXPECT_LE(std::abs(tau[j]), o.effort_limit[j] + 1e-15);
  // The unsaturated controller would have asked for more than the limit at the start.
  Eigen::VectorXd tau(3);
  const Eigen::VectorXd q = plant_start(80).head(3), qd = Eigen::VectorXd::Zero(3);
  const Eigen::VectorXd qdd = f.plan.qdd[0];
  c.compute(0, q, qd, ReferenceSample{f.plan.x[0].head(3), f.plan.x[0].segment(3, 3), qdd}, tau);
  EXPECT_GT(std::abs(tau[2]), 24.0);
  EXPECT_THROW(simulate_closed_loop(f.ex.model, none, c, f.plan, nullptr, plant_start(80),
                                    ClosedLoopOptions{f.ex.integrator(), Eigen::Vector3d(1, -1, 1)}),
               Error);
}

TEST(Control, PDGravityHoldsAStaticReference) {
  // A constant reference at q* with PD + gravity compensation converges to q*.
  const Model m = models::paper_manipulator();
  Eigen::VectorXd qs(3);
  qs << 0.3, 3.5, 0.6;
  Plan plan;
  plan.stages.t0 = 0;
  plan.stages.h = 1e-3;
  plan.stages.n = 3;
  plan.stages.steps = 3000;
  for (long k = 0; k < plan.stages.steps * 4; ++k) {
    for (int i = 0; i < 3; ++i) plan.stages.data.push_back(qs[i]);
    for (int i = 0; i < 6; ++i) plan.stages.data.push_back(0.0);
  }
  Eigen::VectorXd xs = Eigen::VectorXd::Zero(6);
  xs.head(3) = qs;
  plan.t = {0.0, 3.0};
  plan.x = {xs, xs};
  plan.qdd = {Eigen::VectorXd::Zero(3), Eigen::VectorXd::Zero(3)};
  PDGravity c(m, Eigen::Vector3d(400, 400, 2000), Eigen::Vector3d(40, 40, 200));
  ClosedLoopOptions o;
  o.integrator.t1 = 3.0;
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(6);
  x0.head(3) << 0.0, 3.9, 0.5;
  const ClosedLoopResult r = simulate_closed_loop(m, ForceSet{}, c, plan, nullptr, x0, o);
  ASSERT_TRUE(r.summary.ok()) << r.summary.message;
  EXPECT_LT((r.x.back().head(3) - qs).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Feasibility, FlagsTooSmallEffortLimitAtTheRightTimes) {
  Fixture& f = fixture();
  std::vector<Eigen::VectorXd> q, qd, eff;
  Eigen::VectorXd dx(f.rd.state_size());
  for (size_t k = 0; k < f.plan.t.size(); ++k) {
    q.push_back(f.plan.x[k].head(3));
    qd.push_back(f.plan.x[k].segment(3, 3));
    f.rd.derivative(f.plan.t[k], f.plan.x[k], dx);
    eff.push_back(f.rd.constraint_force());
  }
  // Limit joint 3's force to 25 N: the plan needs ~26 N, so it must be flagged exactly where
  // the required |force| exceeds 25.
  ModelDescription d = models::paper_manipulator_description();
  d.links[2].limits.effort = 25.0;
  d.links[0].limits.velocity = 10.0;  // generous: not violated
  const Model m = build_model(d);
  const FeasibilityReport rep = assess_feasibility(m, f.plan.t, q, qd, f.plan.qdd, eff);
  ASSERT_FALSE(rep.feasible());
  ASSERT_EQ(rep.violations.size(), 1u);
  const auto& v = rep.violations[0];
  EXPECT_EQ(v.joint, "z3");
  EXPECT_EQ(v.quantity, "effort");
  ASSERT_FALSE(v.intervals.empty());
  for (size_t k = 0; k < f.plan.t.size(); ++k) {
    bool inside = false;
    for (const auto& iv : v.intervals) inside = inside || (f.plan.t[k] >= iv.first && f.plan.t[k] <= iv.second);
    EXPECT_EQ(inside, std::abs(eff[k][2]) > 25.0) << "t = " << f.plan.t[k];
  }
  EXPECT_NE(rep.text().find("NOT feasible"), std::string::npos);
  EXPECT_NE(rep.json().find("\"feasible\": false"), std::string::npos);
  EXPECT_NEAR(rep.joints[0].peak_speed, 2.5135, 1e-3);  // ψ1's peak speed, cycloid ψ_S/t_S·2 ≈ 2.513
}
