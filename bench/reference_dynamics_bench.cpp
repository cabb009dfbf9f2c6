// Timing of the reference dynamics of the paper's worked example (models::PaperExample) and of
// the runs built on it, with Orocos KDL's constrained hybrid-dynamics solver
// (ChainHdSolver_Vereshchagin) on the same chain and states as the peer. See bench/README.md,
// section "reference_dynamics_bench".
//
//   rd_eval/{projection,lagrange,projection_expr}  one ReferenceDynamics::derivative
//   rd_eval/pinned_{projection,lagrange}            the same with E held instead (3 rows on the 3
//                                                   coordinates: no null space, q̈ = A⁻¹ rhs)
//   kdl/vereshchagin                                one ChainHdSolver_Vereshchagin::CartToJnt
//   constraints/{hand,expr}                         evaluate_constraints (kinematics + rows)
//   constraints/kinematics                          FK + compute_point_states alone
//   constraints/{hand,expr}_rows                    the Constraint::evaluate calls alone
//   plan/run5s, plan/run5s_lagrange                 plan_motion over 0–5 s, RK4, h = 1e-3
//   study/whole, study/closed_loop_one              run_paper_study; one closed loop
//
// The micro-benchmarks cycle through 8 states of the planned motion (t = 0.3, 0.9, …, 4.5 s).
// Before timing, the program checks that the three refdyn routes agree, that KDL's
// Vereshchagin solution satisfies its own constraints (tip acceleration from refdyn's and from
// KDL's kinematics) and the equations of motion with refdyn's inverse dynamics (this settles
// the sign of root_acc), and that Vereshchagin given the paper's own constraint directions
// reproduces refdyn's q̈. It aborts loudly if any check fails.

#include "bench_report.hpp"
#include "dh_tables.hpp"
#include "kdl_peer.hpp"

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/models/paper_study.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

namespace {

using refdyn_bench::KdlPeer;
using Eigen::VectorXd;

constexpr int kStates = 8;            // states cycled through by the micro-benchmarks
constexpr double kGravity = 9.81;     // the paper model's gravity is (0, 0, −9.81)

[[noreturn]] void fatal(const char* what) {
  std::fprintf(stderr, "FATAL: %s\nAborting: the timings would not mean what they claim.\n", what);
  std::fflush(stderr);
  std::abort();
}

// ---------------------------------------------------------------------------------------------
// Set-up shared by all benchmarks (built once in main, before any timing).

struct Bench {
  std::unique_ptr<refdyn::models::PaperExample> ex, ex_expr;
  std::unique_ptr<refdyn::ReferenceDynamics> rd_proj, rd_lag, rd_expr;
  refdyn::ConstraintSet pinned;  // E's x, y, z held where the plan has it at the first state
  std::unique_ptr<refdyn::ReferenceDynamics> rd_pin_proj, rd_pin_lag;
  refdyn::Plan plan;  // the planned motion (projection, hand-written constraints)
  VectorXd x0;
  // The 8 sampled states.
  std::vector<double> t;
  std::vector<VectorXd> x, q, qd;
  VectorXd xdot_proj, xdot_lag, xdot_expr, xdot_pin_proj, xdot_pin_lag;
  // Constraint evaluation workspaces.
  std::unique_ptr<refdyn::Data> data_hand, data_expr, data_kin;
  std::unique_ptr<refdyn::ConstraintEval> ev_hand, ev_expr, ev_kin;
  std::vector<std::vector<refdyn::PointState>> points;  // per state, after the kinematics
  // KDL.
  std::unique_ptr<KdlPeer> kdl;
  // The paper study (for the closed-loop benchmark: its plan, model and plant friction).
  refdyn::models::PaperStudy study;
  refdyn::ClosedLoopOptions clo;
  VectorXd xp_one;
  VectorXd x_end_one;  // final plant state of the study's run with the same start
};

// Spatial linear acceleration of the tip in KDL's convention (base orientation, reference point
// at the tip, root acceleration included): r̈ − ω × ṙ + root. r̈ = C q̈ + d from refdyn's point
// kinematics (evaluate_constraints must have been run on the same q, q̇).
Eigen::Vector3d kdl_linear_acc(const refdyn::PointState& P, const VectorXd& qdd) {
  const Eigen::Vector3d rdd = P.C * qdd + P.d;
  return rdd - P.w.cross(P.v) + Eigen::Vector3d(0, 0, kGravity);
}

void build(Bench& b) {
  using namespace refdyn;
  b.ex = std::make_unique<models::PaperExample>();
  models::PaperExampleParams pe;
  pe.expression_constraints = true;
  b.ex_expr = std::make_unique<models::PaperExample>(pe);
  ReferenceDynamicsOptions o = b.ex->options();
  b.rd_proj = std::make_unique<ReferenceDynamics>(b.ex->model, b.ex->forces, b.ex->constraints, o);
  o.solver = ReferenceSolver::Lagrange;
  b.rd_lag = std::make_unique<ReferenceDynamics>(b.ex->model, b.ex->forces, b.ex->constraints, o);
  b.rd_expr = std::make_unique<ReferenceDynamics>(b.ex_expr->model, b.ex_expr->forces, b.ex_expr->constraints,
                                                  b.ex_expr->options());
  const int n = b.ex->model.nq;
  b.x0 = b.rd_proj->make_state(b.ex->q0(), VectorXd::Zero(n));
  b.plan = plan_motion(*b.rd_proj, b.x0, {b.ex->integrator()});
  if (!b.plan.summary.ok()) fatal(("planning the paper motion failed: " + b.plan.summary.message).c_str());
  for (int k = 0; k < kStates; ++k) {
    const double tk = 0.3 + 0.6 * k;
    const auto it = std::min_element(b.plan.t.begin(), b.plan.t.end(),
                                     [&](double a, double c) { return std::abs(a - tk) < std::abs(c - tk); });
    const size_t i = static_cast<size_t>(it - b.plan.t.begin());
    b.t.push_back(b.plan.t[i]);
    b.x.push_back(b.plan.x[i]);
    b.q.push_back(b.plan.x[i].head(n));
    b.qd.push_back(b.plan.x[i].segment(n, n));
  }
  b.xdot_proj = b.xdot_lag = b.xdot_expr = VectorXd::Zero(b.rd_proj->state_size());
  {  // E pinned: 3 rows on 3 coordinates, the paper's forces
    Data data(b.ex->model);
    forward_kinematics(b.ex->model, data, b.q[0]);
    const Vec3 e = point_position(b.ex->model, data, b.ex->model.point_index("E"));
    for (int axis = 0; axis < 3; ++axis) b.pinned.add(point_coordinate(b.ex->model, "E", axis, constant(e[axis])));
    ReferenceDynamicsOptions po = b.ex->options();
    po.independent.clear();  // every coordinate is dependent
    po.solver = ReferenceSolver::Projection;
    b.rd_pin_proj = std::make_unique<ReferenceDynamics>(b.ex->model, b.ex->forces, b.pinned, po);
    po.solver = ReferenceSolver::Lagrange;
    b.rd_pin_lag = std::make_unique<ReferenceDynamics>(b.ex->model, b.ex->forces, b.pinned, po);
    b.xdot_pin_proj = b.xdot_pin_lag = b.xdot_proj;
  }

  b.data_hand = std::make_unique<Data>(b.ex->model);
  b.data_expr = std::make_unique<Data>(b.ex_expr->model);
  b.data_kin = std::make_unique<Data>(b.ex->model);
  b.ev_hand = std::make_unique<ConstraintEval>(b.ex->model, b.ex->constraints);
  b.ev_expr = std::make_unique<ConstraintEval>(b.ex_expr->model, b.ex_expr->constraints);
  b.ev_kin = std::make_unique<ConstraintEval>(b.ex->model, b.ex->constraints);
  for (int k = 0; k < kStates; ++k) {
    evaluate_constraints(b.ex->model, *b.data_hand, b.ex->constraints, *b.ev_hand, b.t[k], b.q[k], b.qd[k]);
    b.points.push_back(b.ev_hand->points);
  }

  b.kdl = std::make_unique<KdlPeer>(refdyn_bench::paper_table());
  if (b.kdl->dof() != n) fatal("KDL paper chain and refdyn paper model differ in size");
  const double root_acc[6] = {0, 0, kGravity, 0, 0, 0};  // minus gravity (KDL's convention)
  b.kdl->setup_vereshchagin(root_acc, 2);

  // The study and one closed loop of it: α0 = 60°, plant with LuGre friction.
  b.study = models::run_paper_study();
  b.clo.integrator = b.study.example->integrator();
  b.xp_one = VectorXd::Zero(2 * n + b.study.plant_friction.num_states());
  b.xp_one[1] = 1.5 * std::numbers::pi - 60.0 * std::numbers::pi / 180.0;
  b.xp_one[2] = b.study.options.example.z3_0;
  for (const auto& r : b.study.runs)
    if (r.label == "a60_friction") b.x_end_one = r.result.x.back();
  if (b.x_end_one.size() == 0) fatal("the paper study has no run a60_friction");
}

// Vereshchagin inputs for the 8 states: alfa = [unit linear x, unit linear z] at the tip;
// beta = the planned motion's tip acceleration along them (KDL's convention, see
// kdl_linear_acc); ff_torques = the planned applied forces Q (flexible drive on ψ1 + LuGre
// friction on all joints) at the state.
void load_kdl_timing_inputs(Bench& b) {
  const int n = b.ex->model.nq;
  const int E = b.ex->model.point_index("E");
  std::vector<double> q, qd, qdd, alfa, beta, ff;
  for (int k = 0; k < kStates; ++k) {
    b.rd_proj->derivative(b.t[k], b.x[k], b.xdot_proj);
    const VectorXd qdd_k = b.rd_proj->qdd();
    const VectorXd Q = b.rd_proj->applied_force();
    const Eigen::Vector3d acc = kdl_linear_acc(b.points[k][E], qdd_k);
    for (int i = 0; i < n; ++i) {
      q.push_back(b.q[k][i]);
      qd.push_back(b.qd[k][i]);
      qdd.push_back(qdd_k[i]);
      ff.push_back(Q[i]);
    }
    const double ax[6] = {1, 0, 0, 0, 0, 0}, az[6] = {0, 0, 1, 0, 0, 0};
    alfa.insert(alfa.end(), ax, ax + 6);
    alfa.insert(alfa.end(), az, az + 6);
    beta.push_back(acc.x());
    beta.push_back(acc.z());
  }
  b.kdl->load_states(q.data(), qd.data(), qdd.data(), kStates);
  b.kdl->load_vereshchagin_inputs(alfa.data(), beta.data(), ff.data(), kStates);
}

// ---------------------------------------------------------------------------------------------
// Start-up checks.

void check_all(Bench& b) {
  using namespace refdyn;
  const int n = b.ex->model.nq;
  const int E = b.ex->model.point_index("E");
  char msg[512];

  // 1. The three refdyn routes give the same q̈ on the sampled states.
  double worst_routes = 0;
  for (int k = 0; k < kStates; ++k) {
    b.rd_proj->derivative(b.t[k], b.x[k], b.xdot_proj);
    b.rd_lag->derivative(b.t[k], b.x[k], b.xdot_lag);
    b.rd_expr->derivative(b.t[k], b.x[k], b.xdot_expr);
    const double scale = 1.0 + b.xdot_proj.cwiseAbs().maxCoeff();
    worst_routes = std::max({worst_routes, (b.xdot_proj - b.xdot_lag).cwiseAbs().maxCoeff() / scale,
                             (b.xdot_proj - b.xdot_expr).cwiseAbs().maxCoeff() / scale});
  }
  std::printf("check refdyn: projection, lagrange and projection_expr derivatives agree "
              "(worst relative difference %.1e)\n", worst_routes);
  if (!(worst_routes < 1e-9)) fatal("refdyn's projection, Lagrange and expression routes disagree");
  double worst_pinned = 0;  // E pinned: projection (q̈ = K_dc⁻¹ rhs) and Lagrange
  for (int k = 0; k < kStates; ++k) {
    b.rd_pin_proj->derivative(b.t[k], b.x[k], b.xdot_pin_proj);
    b.rd_pin_lag->derivative(b.t[k], b.x[k], b.xdot_pin_lag);
    worst_pinned = std::max(worst_pinned, (b.xdot_pin_proj - b.xdot_pin_lag).cwiseAbs().maxCoeff() /
                                              (1.0 + b.xdot_pin_proj.cwiseAbs().maxCoeff()));
  }
  std::printf("check refdyn: E pinned, projection and lagrange derivatives agree (worst relative difference %.1e)\n",
              worst_pinned);
  if (!(worst_pinned < 1e-9)) fatal("refdyn's projection and Lagrange routes disagree with E pinned");

  // 2. Vereshchagin with the timed inputs: its own constraints hold, and the equations of motion.
  load_kdl_timing_inputs(b);
  std::vector<double> beta_all(2 * kStates);
  double worst_own = 0, worst_fk = 0, worst_kdl_fk = 0, worst_eom = 0, worst_pos = 0;
  for (int k = 0; k < kStates; ++k) {
    // Reconstruct beta as loaded (same formula as load_kdl_timing_inputs).
    b.rd_proj->derivative(b.t[k], b.x[k], b.xdot_proj);
    const Eigen::Vector3d acc_plan = kdl_linear_acc(b.points[k][E], b.rd_proj->qdd());
    const double beta[2] = {acc_plan.x(), acc_plan.z()};
    const VectorXd Q = b.rd_proj->applied_force();
    if (b.kdl->vereshchagin(k) != 0) fatal("ChainHdSolver_Vereshchagin::CartToJnt returned an error");
    VectorXd qdd(n), tau_c(n);
    double acc6[6], pos[3], twist[6], cacc[6];
    b.kdl->get_vereshchagin_qdd(qdd.data());
    b.kdl->get_vereshchagin_constraint_torques(tau_c.data());
    b.kdl->get_vereshchagin_tip_acceleration(acc6);
    const double scale = 1.0 + std::abs(beta[0]) + std::abs(beta[1]);
    // (a) the solver's own tip acceleration: alfaᵀ·acc = beta.
    worst_own = std::max({worst_own, std::abs(acc6[0] - beta[0]) / scale, std::abs(acc6[2] - beta[1]) / scale});
    // (b) refdyn's point kinematics at Vereshchagin's q̈ (independent of KDL).
    const Eigen::Vector3d a_ref = kdl_linear_acc(b.points[k][E], qdd);
    worst_fk = std::max({worst_fk, std::abs(a_ref.x() - beta[0]) / scale, std::abs(a_ref.z() - beta[1]) / scale});
    // (c) KDL's kinematics: FK velocity, J q̈ + J̇ q̇ (classical acceleration) − ω × v + root.
    if (b.kdl->tip_kinematics(k, qdd.data(), pos, twist, cacc) != 0) fatal("KDL tip kinematics failed");
    const Eigen::Vector3d v(twist[0], twist[1], twist[2]), w(twist[3], twist[4], twist[5]);
    const Eigen::Vector3d a_kdl = Eigen::Vector3d(cacc[0], cacc[1], cacc[2]) - w.cross(v) +
                                  Eigen::Vector3d(0, 0, kGravity);
    worst_kdl_fk =
        std::max({worst_kdl_fk, std::abs(a_kdl.x() - beta[0]) / scale, std::abs(a_kdl.z() - beta[1]) / scale});
    worst_pos = std::max(worst_pos, (Eigen::Vector3d(pos[0], pos[1], pos[2]) - b.points[k][E].r).cwiseAbs().maxCoeff());
    // (d) equations of motion: M q̈ + c + g = ff + τ_c (refdyn's RNEA; fails with the wrong root_acc sign).
    const VectorXd tau = inverse_dynamics(b.ex->model, *b.data_kin, b.q[k], b.qd[k], qdd);
    const VectorXd rhs = Q + tau_c;
    worst_eom = std::max(worst_eom, (tau - rhs).cwiseAbs().maxCoeff() / (1.0 + rhs.cwiseAbs().maxCoeff()));
    beta_all[2 * k] = beta[0];
    beta_all[2 * k + 1] = beta[1];
  }
  std::printf("check kdl/vereshchagin (alfa = [x, z] at the tip): alfa^T tip acceleration - beta, relative:\n"
              "      solver's own %.1e, refdyn kinematics %.1e, KDL FK/Jacobian/JacDot %.1e "
              "(tip position refdyn vs KDL %.1e m);\n"
              "      equations of motion M qdd + c + g - (ff + tau_c) %.1e\n",
              worst_own, worst_fk, worst_kdl_fk, worst_pos, worst_eom);
  if (!(worst_own < 1e-9 && worst_fk < 1e-9 && worst_kdl_fk < 1e-9 && worst_pos < 1e-12)) {
    std::snprintf(msg, sizeof msg,
                  "Vereshchagin's constrained acceleration does not satisfy its constraint "
                  "(own %.3e, refdyn kinematics %.3e, KDL kinematics %.3e, position %.3e)",
                  worst_own, worst_fk, worst_kdl_fk, worst_pos);
    fatal(msg);
  }
  if (!(worst_eom < 1e-9)) {
    std::snprintf(msg, sizeof msg,
                  "Vereshchagin's q-ddot violates M qdd + c + g = ff + tau_c by %.3e (root_acc sign?)", worst_eom);
    fatal(msg);
  }

  // 3. Same problem on both sides: alfa = [unit normal of the ellipse cylinder at E, unit z],
  //    beta from refdyn's q̈, ff = Q. Both are ideal constraints on the tip point spanning the
  //    same directions, so Gauss's principle gives the same q̈ as refdyn.
  {
    std::vector<double> alfa, beta, ff;
    std::vector<VectorXd> qdd_rd;
    const double a = b.ex->params.ellipse_a, bb = b.ex->params.ellipse_b;
    for (int k = 0; k < kStates; ++k) {
      b.rd_proj->derivative(b.t[k], b.x[k], b.xdot_proj);
      qdd_rd.push_back(b.rd_proj->qdd());
      const refdyn::PointState& P = b.points[k][E];
      Eigen::Vector3d nrm(2 * P.r.x() / (a * a), 2 * P.r.y() / (bb * bb), 0.0);
      nrm.normalize();
      const Eigen::Vector3d acc = kdl_linear_acc(P, qdd_rd.back());
      const double an[6] = {nrm.x(), nrm.y(), nrm.z(), 0, 0, 0}, az[6] = {0, 0, 1, 0, 0, 0};
      alfa.insert(alfa.end(), an, an + 6);
      alfa.insert(alfa.end(), az, az + 6);
      beta.push_back(nrm.dot(acc));
      beta.push_back(acc.z());
      const VectorXd Q = b.rd_proj->applied_force();
      ff.insert(ff.end(), Q.data(), Q.data() + n);
    }
    b.kdl->load_vereshchagin_inputs(alfa.data(), beta.data(), ff.data(), kStates);
    double worst = 0;
    for (int k = 0; k < kStates; ++k) {
      if (b.kdl->vereshchagin(k) != 0) fatal("ChainHdSolver_Vereshchagin::CartToJnt returned an error");
      VectorXd qdd(n);
      b.kdl->get_vereshchagin_qdd(qdd.data());
      worst = std::max(worst, (qdd - qdd_rd[k]).cwiseAbs().maxCoeff() / (1.0 + qdd_rd[k].cwiseAbs().maxCoeff()));
    }
    std::printf("check same problem (alfa = [ellipse normal, z], beta from refdyn): Vereshchagin qdd vs "
                "refdyn qdd, worst relative difference %.1e\n", worst);
    if (!(worst < 1e-8)) fatal("Vereshchagin given the paper's constraint directions does not reproduce refdyn's qdd");
  }
  load_kdl_timing_inputs(b);  // back to the timed inputs

  // 4. Constraint evaluation: hand-written and expression constraints agree; the rows-only
  //    loop gives what evaluate_constraints gives.
  double worst_c = 0;
  for (int k = 0; k < kStates; ++k) {
    evaluate_constraints(b.ex->model, *b.data_hand, b.ex->constraints, *b.ev_hand, b.t[k], b.q[k], b.qd[k]);
    evaluate_constraints(b.ex_expr->model, *b.data_expr, b.ex_expr->constraints, *b.ev_expr, b.t[k], b.q[k],
                         b.qd[k]);
    const auto& h = *b.ev_hand;
    const auto& e = *b.ev_expr;
    worst_c = std::max({worst_c, (h.phi - e.phi).cwiseAbs().maxCoeff(), (h.phid - e.phid).cwiseAbs().maxCoeff(),
                        (h.A - e.A).cwiseAbs().maxCoeff(), (h.gamma - e.gamma).cwiseAbs().maxCoeff()});
  }
  std::printf("check constraints: hand-written vs expression (phi, phid, A, gamma) worst difference %.1e\n", worst_c);
  if (!(worst_c < 1e-9)) fatal("hand-written and expression constraints disagree");

  // 5. The closed loop timed alone reproduces the study's run.
  {
    auto& s = b.study;
    ComputedTorquePD ctrl(s.example->model, s.options.delta);
    const ClosedLoopResult r =
        simulate_closed_loop(s.example->model, s.plant_friction, ctrl, s.plan, s.rd.get(), b.xp_one, b.clo);
    const double d = (r.x.back() - b.x_end_one).cwiseAbs().maxCoeff();
    std::printf("check study: whole study %s (plan %s, %zu closed loops); closed_loop_one (a60_friction) "
                "reproduces the study's run (final state difference %.1e)\n",
                s.plan.summary.ok() ? "ok" : "FAILED", s.plan.summary.ok() ? "ok" : "failed", s.runs.size(), d);
    if (!r.summary.ok() || !(d < 1e-12)) fatal("the single closed loop does not reproduce the study's run");
  }
}

// ---------------------------------------------------------------------------------------------
// Benchmarks.

auto min_stat() {
  return [](const std::vector<double>& v) { return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end()); };
}

template <typename F>
benchmark::internal::Benchmark* reg_states(const std::string& name, F f) {
  return benchmark::RegisterBenchmark(name.c_str(),
                                      [f](benchmark::State& st) {
                                        unsigned k = 0;
                                        for (auto _ : st) {
                                          f(static_cast<int>(k++ % kStates));
                                          benchmark::ClobberMemory();
                                        }
                                      })
      ->Unit(benchmark::kNanosecond)
      ->ComputeStatistics("min", min_stat());
}

template <typename F>
benchmark::internal::Benchmark* reg_run(const std::string& name, F f) {
  return benchmark::RegisterBenchmark(name.c_str(),
                                      [f](benchmark::State& st) {
                                        for (auto _ : st) {
                                          f();
                                          benchmark::ClobberMemory();
                                        }
                                      })
      ->Unit(benchmark::kMillisecond)
      ->ComputeStatistics("min", min_stat());
}

void register_all(Bench* b) {
  using namespace refdyn;
  // 1. One reference-dynamics evaluation, per route (the unique_ptr members are set by build()).
  const std::pair<const char*, std::pair<ReferenceDynamics*, VectorXd*>> routes[] = {
      {"rd_eval/projection", {b->rd_proj.get(), &b->xdot_proj}},
      {"rd_eval/lagrange", {b->rd_lag.get(), &b->xdot_lag}},
      {"rd_eval/projection_expr", {b->rd_expr.get(), &b->xdot_expr}},
      {"rd_eval/pinned_projection", {b->rd_pin_proj.get(), &b->xdot_pin_proj}},
      {"rd_eval/pinned_lagrange", {b->rd_pin_lag.get(), &b->xdot_pin_lag}}};
  for (const auto& [name, route] : routes)
    reg_states(name, [b, rd = route.first, xdot = route.second](int k) {
      rd->derivative(b->t[k], b->x[k], *xdot);
      benchmark::DoNotOptimize(xdot->data());
    });
  // 2. The peer.
  reg_states("kdl/vereshchagin", [b](int k) { benchmark::DoNotOptimize(b->kdl->vereshchagin(k)); });
  // 3. Constraints.
  reg_states("constraints/hand", [b](int k) {
    evaluate_constraints(b->ex->model, *b->data_hand, b->ex->constraints, *b->ev_hand, b->t[k], b->q[k], b->qd[k]);
    benchmark::DoNotOptimize(b->ev_hand->A.data());
  });
  reg_states("constraints/expr", [b](int k) {
    evaluate_constraints(b->ex_expr->model, *b->data_expr, b->ex_expr->constraints, *b->ev_expr, b->t[k], b->q[k],
                         b->qd[k]);
    benchmark::DoNotOptimize(b->ev_expr->A.data());
  });
  reg_states("constraints/kinematics", [b](int k) {
    // What evaluate_constraints does before the rows: FK + point kinematics of the set's points.
    unchecked::forward_kinematics(b->ex->model, *b->data_kin, b->q[k]);
    compute_point_states(b->ex->model, *b->data_kin, b->ex->constraints.points(), b->qd[k], b->ev_kin->points);
    benchmark::DoNotOptimize(b->ev_kin->points.data());
  });
  auto rows = [b](const ConstraintSet& set, ConstraintEval& ev, int k) {
    // What evaluate_constraints does after the kinematics, on precomputed point states.
    const ConstraintInput in{b->t[k], b->q[k], b->qd[k], b->points[k], ev.scratch.data()};
    for (int c = 0; c < set.size(); ++c) {
      const auto& con = set.constraints()[c];
      const int r = set.row_offset(c), m = con->rows();
      con->evaluate(in, ev.phi.segment(r, m), ev.phid.segment(r, m), ev.A.middleRows(r, m), ev.gamma.segment(r, m));
    }
    benchmark::DoNotOptimize(ev.A.data());
  };
  reg_states("constraints/hand_rows", [b, rows](int k) { rows(b->ex->constraints, *b->ev_hand, k); });
  reg_states("constraints/expr_rows", [b, rows](int k) { rows(b->ex_expr->constraints, *b->ev_expr, k); });
  // 4. The spec run.
  reg_run("plan/run5s", [b] {
    const Plan p = plan_motion(*b->rd_proj, b->x0, {b->ex->integrator()});
    benchmark::DoNotOptimize(p.x.back().data());
  });
  reg_run("plan/run5s_lagrange", [b] {
    const Plan p = plan_motion(*b->rd_lag, b->x0, {b->ex->integrator()});
    benchmark::DoNotOptimize(p.x.back().data());
  });
  // 5. The study.
  reg_run("study/whole", [] {
    const models::PaperStudy s = models::run_paper_study();
    benchmark::DoNotOptimize(s.runs.back().result.x.back().data());
  });
  reg_run("study/closed_loop_one", [b] {
    auto& s = b->study;
    ComputedTorquePD ctrl(s.example->model, s.options.delta);
    const ClosedLoopResult r =
        simulate_closed_loop(s.example->model, s.plant_friction, ctrl, s.plan, s.rd.get(), b->xp_one, b->clo);
    benchmark::DoNotOptimize(r.x.back().data());
  });
}

// ---------------------------------------------------------------------------------------------
// Reporting (as in dynamics_bench): the console shows the median and min aggregates; every
// repetition is collected for the final table.

using refdyn_bench::fmt_ns;
using refdyn_bench::fmt_ratio;
using refdyn_bench::Reporter;
using refdyn_bench::Stats;

void print_tables(const Reporter& rep) {
  auto get = [&](const std::string& key) -> const Stats* {
    auto it = rep.stats.find(key);
    return it == rep.stats.end() ? nullptr : &it->second;
  };
  auto med = [&](const std::string& k) { const Stats* s = get(k); return s ? s->median() : NAN; };
  auto mn = [&](const std::string& k) { const Stats* s = get(k); return s ? s->min() : NAN; };

  std::printf("\nCPU time per call: 'med' = median over the repetitions, 'min' = fastest repetition.\n\n");
  std::printf("| benchmark | med | min | target |\n|---|---:|---:|---|\n");
  const std::vector<std::pair<std::string, std::string>> rows = {
      {"rd_eval/projection", "kdl/vereshchagin / this >= 4"},
      {"rd_eval/lagrange", ""},
      {"rd_eval/projection_expr", ""},
      {"rd_eval/pinned_projection", "(E pinned: 3 rows, q̈ = A⁻¹ rhs)"},
      {"rd_eval/pinned_lagrange", ""},
      {"kdl/vereshchagin", "(peer)"},
      {"constraints/hand", ""},
      {"constraints/expr", "this / constraints/hand <= 2"},
      {"constraints/kinematics", "(FK + point states, part of both)"},
      {"constraints/hand_rows", ""},
      {"constraints/expr_rows", ""},
      {"plan/run5s", "< 25 ms"},
      {"plan/run5s_lagrange", ""},
      {"study/whole", "<= 200 ms"},
      {"study/closed_loop_one", ""},
  };
  for (const auto& [name, target] : rows) {
    if (!get(name)) continue;
    std::printf("| `%s` | %s | %s | %s |\n", name.c_str(), fmt_ns(med(name)).c_str(), fmt_ns(mn(name)).c_str(),
                target.c_str());
  }

  auto verdict = [](double v, double lim, bool at_least) {
    if (!std::isfinite(v)) return "-";
    return (at_least ? v >= lim : v <= lim) ? "met" : "NOT met";
  };
  std::printf("\nRatios (med/med, min/min) and targets:\n\n");
  std::printf("| ratio | med | min | target | med meets | min meets |\n|---|---:|---:|---|---|---|\n");
  auto ratio = [&](const char* label, double rm, double rn, const char* target, double lim, bool at_least) {
    std::printf("| %s | %s | %s | %s | %s | %s |\n", label, fmt_ratio(rm).c_str(), fmt_ratio(rn).c_str(), target,
                lim > 0 ? verdict(rm, lim, at_least) : "", lim > 0 ? verdict(rn, lim, at_least) : "");
  };
  auto r = [&](const std::string& a, const std::string& b, bool use_min) {
    return use_min ? mn(a) / mn(b) : med(a) / med(b);
  };
  ratio("kdl/vereshchagin / rd_eval/projection", r("kdl/vereshchagin", "rd_eval/projection", false),
        r("kdl/vereshchagin", "rd_eval/projection", true), ">= 4", 4.0, true);
  ratio("rd_eval/lagrange / rd_eval/projection", r("rd_eval/lagrange", "rd_eval/projection", false),
        r("rd_eval/lagrange", "rd_eval/projection", true), "", 0, true);
  ratio("rd_eval/projection_expr / rd_eval/projection", r("rd_eval/projection_expr", "rd_eval/projection", false),
        r("rd_eval/projection_expr", "rd_eval/projection", true), "", 0, true);
  ratio("constraints/expr / constraints/hand", r("constraints/expr", "constraints/hand", false),
        r("constraints/expr", "constraints/hand", true), "<= 2", 2.0, false);
  ratio("constraints/expr_rows / constraints/hand_rows", r("constraints/expr_rows", "constraints/hand_rows", false),
        r("constraints/expr_rows", "constraints/hand_rows", true), "(rows alone)", 0, false);
  {
    const double km = med("constraints/kinematics"), kn = mn("constraints/kinematics");
    ratio("(expr - kinematics) / (hand - kinematics)",
          (med("constraints/expr") - km) / (med("constraints/hand") - km),
          (mn("constraints/expr") - kn) / (mn("constraints/hand") - kn), "(by subtraction)", 0, false);
  }
  ratio("plan/run5s_lagrange / plan/run5s", r("plan/run5s_lagrange", "plan/run5s", false),
        r("plan/run5s_lagrange", "plan/run5s", true), "", 0, true);
  auto absolute = [&](const char* name, double limit_ms, const char* target) {
    const double m = med(name) / 1e6, n = mn(name) / 1e6;
    char lm[32], ln[32];
    std::snprintf(lm, sizeof lm, "%.1f ms", m);
    std::snprintf(ln, sizeof ln, "%.1f ms", n);
    std::printf("| %s (absolute) | %s | %s | %s | %s | %s |\n", name, lm, ln, target, verdict(m, limit_ms, false),
                verdict(n, limit_ms, false));
  };
  if (get("plan/run5s")) absolute("plan/run5s", 25.0, "< 25 ms");
  if (get("study/whole")) absolute("study/whole", 200.0, "<= 200 ms");
}

}  // namespace

int main(int argc, char** argv) {
  // Defaults (overridable on the command line, later flags win): interleaved repetitions.
  if (!refdyn_bench::initialize_with_defaults(argc, argv)) return 1;

  auto b = std::make_unique<Bench>();
  build(*b);
  check_all(*b);
  std::printf("\n");
  std::fflush(stdout);

  register_all(b.get());
  Reporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  print_tables(reporter);
  benchmark::Shutdown();
  return 0;
}
