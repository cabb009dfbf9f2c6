// Side-by-side timing of refdyn's recursive route, refdyn's trace route, Orocos KDL and MuJoCo
// on the same models: the paper manipulator and random 7-, 15-, 30- and 60-DOF chains built from
// the same seeded standard-DH tables on both sides (dh_tables.hpp; MuJoCo gets an MJCF written
// from refdyn's model, mujoco_peer.hpp). See bench/README.md.
//
// Before timing, every model is checked once: M, g, c + g and τ from refdyn's recursive route,
// refdyn's trace route, KDL and MuJoCo (M, c + g, τ, q̈) must agree to 1e-10 (relative to the
// largest entry); the program aborts loudly otherwise. At the end it prints the table of ratios
// peer / refdyn.
//
// Forward dynamics (FD: CRBA + Cholesky, the articulated-body algorithm, the automatic choice,
// KDL's ChainFdSolver_RNE) and constrained forward dynamics are timed in the same run; their own
// table follows. CFD: one reference-dynamics evaluation with 4 constraint rows (tip x, y, z and a
// joint coupling) by projection, Lagrange/KKT and the automatic choice; KDL has no solver for a
// joint coupling, so its peer there is KDL's M, c, g plus an Eigen KKT solve written for this
// benchmark ("kdl_kkt"). CFDtip: the tip frame's origin held (3 rows), the case KDL's own
// constrained solver ChainHdSolver_Vereshchagin handles ("kdl_vereshchagin"), timed next to the
// same KKT peer. Every peer figure is printed with the KDL routine it calls.

#include "bench_report.hpp"
#include "dh_models.hpp"
#include "dh_tables.hpp"
#include "kdl_peer.hpp"
#include "mujoco_peer.hpp"

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/io/urdf.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/expression/time_function.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

using refdyn_bench::DHTable;
using refdyn_bench::KdlPeer;
using refdyn_bench::KdlUrdfPeer;
using refdyn_bench::MujocoPeer;

constexpr int kStates = 8;  // states cycled through by every timed loop (same for all sides)

refdyn::Model model_from_table(const DHTable& t) {
  refdyn::ModelDescription d = refdyn_bench::description_from_table(t);
  d.add_point("tip", d.links.back().name, refdyn::Vec3(0.05, 0.0, 0.0));  // for the constrained FD
  d.add_point("ee", d.links.back().name, refdyn::Vec3::Zero());  // KDL's tip frame origin (CFDtip)
  return refdyn::build_model(d);
}

struct Case {
  explicit Case(refdyn::Model m) : model(std::move(m)) {}
  std::string name;
  refdyn::Model model;
  std::unique_ptr<refdyn::Data> data;
  std::unique_ptr<KdlPeer> kdl;
  std::unique_ptr<MujocoPeer> mujoco;
  std::vector<Eigen::VectorXd> q, qd, qdd, tau;
  // Constrained FD (models with a "tip" point and at least 5 DOF): 4 rows, no applied forces.
  refdyn::ForceSet forces;
  refdyn::ConstraintSet constraints;
  std::unique_ptr<refdyn::ReferenceDynamics> rd_proj, rd_lag, rd_auto;
  std::vector<Eigen::VectorXd> x;
  Eigen::VectorXd xdot;
  bool constrained = false;
  // CFDtip (same models): "ee" (the last DH frame's origin = KDL's tip) held at its state-0
  // position, 3 rows; a second KDL peer holds these rows (KKT) and the Vereshchagin inputs.
  refdyn::ConstraintSet tip_constraints;
  std::unique_ptr<refdyn::ReferenceDynamics> rd_tip_proj, rd_tip_lag, rd_tip_auto;
  std::unique_ptr<KdlPeer> kdl_tip;
  std::vector<Eigen::VectorXd> x_tip;
  bool tip = false;
  bool crossover_only = false;  ///< only the FD and CFD benchmarks (sizes for the crossovers)
  bool check_only = false;      ///< checked against KDL at start-up, not timed (armature cases)
};

/// Constrained FD: the tip's x, y and z held at their values in state 0 (point_coordinate) and
/// joint 2 coupled to joint 1 (joint_coupling, ratio 0.5): 4 rows, Baumgarte terms active (the
/// states are not consistent). The KDL peer gets the same A and right-hand side
/// (A q̈ = −γ − 2αΦ̇ − β²Φ) per state, computed once here from refdyn's evaluation.
void setup_constrained(Case& c) {
  using namespace refdyn;
  const Model& m = c.model;
  Data data(m);
  forward_kinematics(m, data, c.q[0]);
  const Vec3 tip = point_position(m, data, m.point_index("tip"));
  for (int axis = 0; axis < 3; ++axis) c.constraints.add(point_coordinate(m, "tip", axis, constant(tip[axis])));
  c.constraints.add(joint_coupling(m, m.joint_name[1], m.joint_name[0], 0.5));
  ReferenceDynamicsOptions o;
  o.automatic_partition = true;
  o.solver = ReferenceSolver::Projection;
  c.rd_proj = std::make_unique<ReferenceDynamics>(m, c.forces, c.constraints, o);
  o.solver = ReferenceSolver::Lagrange;
  c.rd_lag = std::make_unique<ReferenceDynamics>(m, c.forces, c.constraints, o);
  o.solver = ReferenceSolver::Automatic;
  c.rd_auto = std::make_unique<ReferenceDynamics>(m, c.forces, c.constraints, o);
  const int n = m.nq, rows = c.constraints.rows();
  std::vector<double> A(static_cast<size_t>(kStates) * rows * n), rhs(static_cast<size_t>(kStates) * rows);
  for (int k = 0; k < kStates; ++k) {
    c.x.push_back(c.rd_lag->make_state(c.q[k], c.qd[k]));
    c.xdot = Eigen::VectorXd::Zero(c.x[k].size());
    c.rd_lag->derivative(0.0, c.x[k], c.xdot);
    const ConstraintEval& ev = c.rd_lag->constraints();
    Eigen::Map<Eigen::MatrixXd>(A.data() + static_cast<size_t>(k) * rows * n, rows, n) = ev.A;
    for (int r = 0; r < rows; ++r)
      rhs[k * rows + r] = -ev.gamma[r] - 2.0 * o.alpha * ev.phid[r] - o.beta * o.beta * ev.phi[r];
  }
  c.kdl->set_constraints(A.data(), rhs.data(), rows, kStates);
  c.constrained = true;
}

/// CFDtip: the point "ee" (the origin of the last DH frame, KDL's tip) held at its state-0
/// position, 3 rows, no applied forces, the Baumgarte terms active. Peers: KDL's own constrained
/// solver, ChainHdSolver_Vereshchagin with alfa = unit x, y, z (linear) at the tip and beta = the
/// tip acceleration refdyn's solution has (KDL's convention: the spatial acceleration at the tip,
/// r̈ − ω × v, plus root_acc = −gravity) — by Gauss's principle the same problem, so the same q̈
/// (checked); and the KKT peer with the same A and right-hand side.
void setup_tip(Case& c, const DHTable& table) {
  using namespace refdyn;
  const Model& m = c.model;
  Data data(m);
  const int ee = m.point_index("ee");
  forward_kinematics(m, data, c.q[0]);
  const Vec3 r0 = point_position(m, data, ee);
  for (int axis = 0; axis < 3; ++axis) c.tip_constraints.add(point_coordinate(m, "ee", axis, constant(r0[axis])));
  ReferenceDynamicsOptions o;
  o.automatic_partition = true;
  o.solver = ReferenceSolver::Projection;
  c.rd_tip_proj = std::make_unique<ReferenceDynamics>(m, c.forces, c.tip_constraints, o);
  o.solver = ReferenceSolver::Lagrange;
  c.rd_tip_lag = std::make_unique<ReferenceDynamics>(m, c.forces, c.tip_constraints, o);
  o.solver = ReferenceSolver::Automatic;
  c.rd_tip_auto = std::make_unique<ReferenceDynamics>(m, c.forces, c.tip_constraints, o);
  c.kdl_tip = std::make_unique<KdlPeer>(table);
  const int n = m.nq, rows = 3;
  std::vector<double> q, qd, A(static_cast<size_t>(kStates) * rows * n), rhs(static_cast<size_t>(kStates) * rows);
  std::vector<double> alfa, beta, ff(static_cast<size_t>(kStates) * n, 0.0);
  const Vec3 gravity = m.gravity;
  for (int k = 0; k < kStates; ++k) {
    q.insert(q.end(), c.q[k].data(), c.q[k].data() + n);
    qd.insert(qd.end(), c.qd[k].data(), c.qd[k].data() + n);
    c.x_tip.push_back(c.rd_tip_lag->make_state(c.q[k], c.qd[k]));
    Eigen::VectorXd xdot = Eigen::VectorXd::Zero(c.x_tip[k].size());
    c.rd_tip_lag->derivative(0.0, c.x_tip[k], xdot);
    const ConstraintEval& ev = c.rd_tip_lag->constraints();
    Eigen::Map<Eigen::MatrixXd>(A.data() + static_cast<size_t>(k) * rows * n, rows, n) = ev.A;
    for (int r = 0; r < rows; ++r)
      rhs[k * rows + r] = -ev.gamma[r] - 2.0 * o.alpha * ev.phid[r] - o.beta * o.beta * ev.phi[r];
    const PointState& P = ev.points[ee];
    const Vec3 acc = P.C * xdot.segment(n, n) + P.d - P.w.cross(P.v) - gravity;
    for (int r = 0; r < rows; ++r) {
      double a6[6] = {0, 0, 0, 0, 0, 0};
      a6[r] = 1.0;
      alfa.insert(alfa.end(), a6, a6 + 6);
      beta.push_back(acc[r]);
    }
  }
  const std::vector<double> qdd(static_cast<size_t>(kStates) * n, 0.0);
  c.kdl_tip->load_states(q.data(), qd.data(), qdd.data(), kStates);
  c.kdl_tip->set_constraints(A.data(), rhs.data(), rows, kStates);
  const double root_acc[6] = {-gravity.x(), -gravity.y(), -gravity.z(), 0, 0, 0};  // KDL: minus gravity
  c.kdl_tip->setup_vereshchagin(root_acc, rows);
  c.kdl_tip->load_vereshchagin_inputs(alfa.data(), beta.data(), ff.data(), kStates);
  c.tip = true;
}

std::unique_ptr<Case> make_case(const DHTable& table, refdyn::Model model, std::uint32_t seed, bool tip = false) {
  auto c = std::make_unique<Case>(std::move(model));
  c->name = table.name;
  c->data = std::make_unique<refdyn::Data>(c->model);
  c->kdl = std::make_unique<KdlPeer>(table);
  const int n = c->model.nq;
  if (c->kdl->dof() != n) {
    std::fprintf(stderr, "FATAL: %s: KDL chain has %d joints, refdyn model %d\n", c->name.c_str(),
                 c->kdl->dof(), n);
    std::exit(2);
  }
  const auto q = refdyn_bench::random_states(n, kStates, 3.0, seed);
  const auto qd = refdyn_bench::random_states(n, kStates, 2.0, seed + 1);
  const auto qdd = refdyn_bench::random_states(n, kStates, 5.0, seed + 2);
  const auto tau = refdyn_bench::random_states(n, kStates, 20.0, seed + 3);
  c->kdl->load_states(q.data(), qd.data(), qdd.data(), kStates);
  c->kdl->load_torques(tau.data(), kStates);
  for (int k = 0; k < kStates; ++k) {
    c->q.push_back(Eigen::Map<const Eigen::VectorXd>(q.data() + k * n, n));
    c->qd.push_back(Eigen::Map<const Eigen::VectorXd>(qd.data() + k * n, n));
    c->qdd.push_back(Eigen::Map<const Eigen::VectorXd>(qdd.data() + k * n, n));
    c->tau.push_back(Eigen::Map<const Eigen::VectorXd>(tau.data() + k * n, n));
  }
  c->mujoco = std::make_unique<MujocoPeer>(c->model);
  c->mujoco->load_states(c->q, c->qd, c->qdd, c->tau);
  if (n >= 5 && !c->model.point_name.empty()) setup_constrained(*c);  // 4 rows: n ≥ 5
  if (tip && c->constrained) setup_tip(*c, table);
  return c;
}

// ---------------------------------------------------------------------------------------------
// Start-up agreement check.

double rel_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const double scale = std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), 1e-300});
  return (a - b).cwiseAbs().maxCoeff() / scale;
}

/// FD and CFD: every route's q̈ against the others. Each is backward stable, so two of them may
/// differ by cond(M)·ε relative: the bound is 1e-13·cond(M) + 1e-13 (cond(M) computed here).
bool check_forward_dynamics(Case& c) {
  const int n = c.model.nq;
  refdyn::Data& data = *c.data;
  bool ok = true;
  double worst = 0, worst_c = 0, worst_cond = 0;
  auto expect = [&](const char* what, int k, const Eigen::VectorXd& a, const Eigen::VectorXd& b, double tol,
                    double& w) {
    const double d = (a - b).cwiseAbs().maxCoeff() / std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), 1e-300});
    w = std::max(w, d);
    if (!(d <= tol)) {
      ok = false;
      std::fprintf(stderr, "FATAL: %s state %d: %s differ, relative max difference %.3e > %.1e\n", c.name.c_str(), k,
                   what, d, tol);
    }
  };
  Eigen::VectorXd kq(n);
  for (int k = 0; k < kStates; ++k) {
    const Eigen::MatrixXd M = refdyn::mass_matrix(c.model, data, c.q[k]);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
    const double cond = es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
    worst_cond = std::max(worst_cond, cond);
    const double tol = 1e-13 * cond + 1e-13;
    const Eigen::VectorXd crba = refdyn::forward_dynamics_crba(c.model, data, c.q[k], c.qd[k], c.tau[k]);
    const Eigen::VectorXd aba = refdyn::forward_dynamics_aba(c.model, data, c.q[k], c.qd[k], c.tau[k]);
    const Eigen::VectorXd automatic = refdyn::forward_dynamics(c.model, data, c.q[k], c.qd[k], c.tau[k]);
    if (c.kdl->forward_dynamics(k) != 0) {
      std::fprintf(stderr, "FATAL: %s: KDL ChainFdSolver_RNE returned an error\n", c.name.c_str());
      return false;
    }
    c.kdl->get_qdd(kq.data());
    expect("FD: ABA vs CRBA + Cholesky", k, aba, crba, tol, worst);
    expect("FD: automatic vs its choice", k, automatic, refdyn::forward_dynamics_uses_aba(n) ? aba : crba, 0.0, worst);
    expect("FD: refdyn vs KDL ChainFdSolver_RNE", k, automatic, kq, tol, worst);
    c.mujoco->time_forward_dynamics(k);
    expect("FD: refdyn vs MuJoCo CRB + factorM + RNE + solveM", k, automatic, c.mujoco->last_qdd(), tol, worst);
    if (!c.constrained) continue;
    Eigen::VectorXd xp = c.xdot, xl = c.xdot, xa = c.xdot;
    c.rd_proj->derivative(0.0, c.x[k], xp);
    c.rd_lag->derivative(0.0, c.x[k], xl);
    c.rd_auto->derivative(0.0, c.x[k], xa);
    if (c.kdl->constrained_forward_dynamics(k) != 0) {
      std::fprintf(stderr, "FATAL: %s: the KDL KKT peer failed\n", c.name.c_str());
      return false;
    }
    c.kdl->get_qdd(kq.data());
    expect("CFD: projection vs Lagrange", k, xp.segment(n, n), xl.segment(n, n), 1e3 * tol, worst_c);
    expect("CFD: automatic vs its choice", k, xa,
           c.rd_auto->options().solver == refdyn::ReferenceSolver::Lagrange ? xl : xp, 0.0, worst_c);
    expect("CFD: refdyn Lagrange vs KDL M, c, g + KKT", k, xl.segment(n, n), kq, 1e3 * tol, worst_c);
    if (!c.tip) continue;
    Eigen::VectorXd tp = Eigen::VectorXd::Zero(c.x_tip[k].size()), tl = tp, ta = tp;
    c.rd_tip_proj->derivative(0.0, c.x_tip[k], tp);
    c.rd_tip_lag->derivative(0.0, c.x_tip[k], tl);
    c.rd_tip_auto->derivative(0.0, c.x_tip[k], ta);
    expect("CFDtip: projection vs Lagrange", k, tp.segment(n, n), tl.segment(n, n), 1e3 * tol, worst_c);
    expect("CFDtip: automatic vs its choice", k, ta,
           c.rd_tip_auto->options().solver == refdyn::ReferenceSolver::Lagrange ? tl : tp, 0.0, worst_c);
    if (c.kdl_tip->constrained_forward_dynamics(k) != 0 || c.kdl_tip->vereshchagin(k) != 0) {
      std::fprintf(stderr, "FATAL: %s: the KDL KKT peer or ChainHdSolver_Vereshchagin failed\n", c.name.c_str());
      return false;
    }
    c.kdl_tip->get_qdd(kq.data());
    expect("CFDtip: refdyn Lagrange vs KDL M, c, g + KKT", k, tl.segment(n, n), kq, 1e3 * tol, worst_c);
    c.kdl_tip->get_vereshchagin_qdd(kq.data());
    expect("CFDtip: refdyn Lagrange vs KDL ChainHdSolver_Vereshchagin", k, tl.segment(n, n), kq, 1e3 * tol, worst_c);
    double pos[3], twist[6], acc[6];
    if (c.kdl_tip->tip_kinematics(k, kq.data(), pos, twist, acc) != 0) return false;
    refdyn::forward_kinematics(c.model, data, c.q[k]);
    const refdyn::Vec3 ee = refdyn::point_position(c.model, data, c.model.point_index("ee"));
    expect("CFDtip: refdyn point ee vs KDL's tip position", k, ee, Eigen::Vector3d(pos[0], pos[1], pos[2]), 1e-12,
           worst_c);
  }
  std::printf("check %-8s %2d DOF: FD routes, KDL and MuJoCo agree (worst %.1e, cond(M) up to %.1e)", c.name.c_str(), n,
              worst, worst_cond);
  if (c.constrained)
    std::printf("; CFD%s routes and KDL peers%s agree (worst %.1e)", c.tip ? " and CFDtip" : "",
                c.tip ? " (KKT, Vereshchagin)" : " (KKT)", worst_c);
  std::printf("\n");
  return ok;
}

/// Comparisons of one model at one tolerance: the worst relative difference, and a FATAL line
/// on stderr for every one above the tolerance.
struct Agreement {
  std::string model;
  double tol;
  bool ok = true;
  double worst = 0;
  void expect(const char* what, int k, const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    const double d = rel_diff(a, b);
    worst = std::max(worst, d);
    if (!(d <= tol)) {
      ok = false;
      std::fprintf(stderr, "FATAL: %s state %d: %s differ, relative max difference %.3e > %.0e\n", model.c_str(), k,
                   what, d, tol);
    }
  }
};

bool check_case(Case& c, double tol) {
  const int n = c.model.nq;
  refdyn::Data& data = *c.data;
  Agreement agree{c.name, tol};
  Eigen::MatrixXd Mk(n, n);
  Eigen::VectorXd ck(n), gk(n), tk(n);
  for (int k = 0; k < kStates; ++k) {
    if (c.kdl->mass_matrix(k) != 0 || c.kdl->coriolis(k) != 0 || c.kdl->gravity(k) != 0 ||
        c.kdl->inverse_dynamics(k) != 0) {
      std::fprintf(stderr, "FATAL: %s: a KDL solver returned an error\n", c.name.c_str());
      return false;
    }
    c.kdl->get_mass_matrix(Mk.data());
    c.kdl->get_coriolis(ck.data());
    c.kdl->get_gravity(gk.data());
    c.kdl->get_tau(tk.data());
    const Eigen::MatrixXd M = refdyn::mass_matrix(c.model, data, c.q[k]);
    agree.expect("M: refdyn recursive vs KDL JntToMass", k, M, Mk);
    agree.expect("M: refdyn recursive vs refdyn trace", k, M, refdyn::trace_mass_matrix(c.model, data, c.q[k]));
    const Eigen::VectorXd g = refdyn::gravity_forces(c.model, data, c.q[k]);
    agree.expect("g: refdyn recursive vs KDL JntToGravity", k, g, gk);
    const Eigen::VectorXd cg = refdyn::bias_forces(c.model, data, c.q[k], c.qd[k]);
    agree.expect("c+g: refdyn recursive vs KDL JntToCoriolis+JntToGravity", k, cg, ck + gk);
    const Eigen::VectorXd cg_trace = refdyn::trace_coriolis(c.model, data, c.q[k], c.qd[k]) +
                                     refdyn::trace_gravity(c.model, data, c.q[k]);
    agree.expect("c+g: refdyn recursive vs refdyn trace", k, cg, cg_trace);
    const Eigen::VectorXd tau = refdyn::inverse_dynamics(c.model, data, c.q[k], c.qd[k], c.qdd[k]);
    agree.expect("tau: refdyn RNEA vs KDL ChainIdSolver_RNE", k, tau, tk);
    agree.expect("tau: refdyn RNEA vs M qdd + c + g", k, tau, M * c.qdd[k] + cg);
    // MuJoCo through the timed calls themselves (stored state k).
    c.mujoco->time_mass_matrix(k);
    agree.expect("M: refdyn recursive vs MuJoCo mj_crb + mj_fullM", k, M, c.mujoco->last_mass_matrix());
    c.mujoco->time_bias_forces(k);
    agree.expect("c+g: refdyn recursive vs MuJoCo mj_rne (qacc = 0)", k, cg, c.mujoco->last_bias_forces());
    c.mujoco->time_inverse_dynamics(k);
    agree.expect("tau: refdyn RNEA vs MuJoCo mj_rne", k, tau, c.mujoco->last_tau());
  }
  std::printf("check %-8s %2d DOF: recursive, trace, KDL and MuJoCo agree (worst relative difference %.1e)\n",
              c.name.c_str(), n, agree.worst);
  return check_forward_dynamics(c) && agree.ok;
}

/// The same URDF file read by refdyn's loader (io/urdf.hpp) and by KDL's (kdl_parser, into a
/// KDL::Tree): M, c + g, g and τ from refdyn against KDL's TreeIdSolver_RNE (M column by column
/// as τ(q, 0, e_j) − τ(q, 0, 0)), coordinates matched by joint name, 8 random states. KDL reads
/// no armature from a URDF (refdyn takes it from Drake's rotor tags), so refdyn's is set to zero
/// here. This checks refdyn's URDF reading (frames, rpy, inertial origins, fixed links folded,
/// continuous and mimic joints) against an independent reader, not only its dynamics.
bool check_urdf(const std::string& path, double tol) {
  std::vector<refdyn::io::UrdfMimic> mimics;  // KDL reads a mimic joint as a joint, and so does the model
  refdyn::ModelDescription desc = refdyn::io::load_urdf(path, {}, &mimics);
  for (refdyn::LinkSpec& l : desc.links) l.armature = 0.0;
  const refdyn::Model m = refdyn::build_model(desc);
  refdyn::Data data(m);
  const int n = m.nq;
  const double gravity[3] = {m.gravity.x(), m.gravity.y(), m.gravity.z()};
  KdlUrdfPeer kdl(path, gravity);
  const std::string file = path.substr(path.find_last_of('/') + 1);
  if (kdl.dof() != n) {
    std::fprintf(stderr, "FATAL: %s: KDL reads %d joints, refdyn %d\n", file.c_str(), kdl.dof(), n);
    return false;
  }
  std::vector<int> index(n);  // refdyn coordinate of KDL's coordinate i
  for (int i = 0; i < n; ++i) index[i] = m.joint_index(kdl.joint_name(i));
  auto to_kdl = [&](const Eigen::VectorXd& x) {
    Eigen::VectorXd y(n);
    for (int i = 0; i < n; ++i) y[i] = x[index[i]];
    return y;
  };
  auto kdl_tau = [&](const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) {
    const Eigen::VectorXd kq = to_kdl(q), kqd = to_kdl(qd), kqdd = to_kdl(qdd);
    Eigen::VectorXd kt(n), t(n);
    if (kdl.inverse_dynamics(kq.data(), kqd.data(), kqdd.data(), kt.data()) != 0) {
      std::fprintf(stderr, "FATAL: %s: KDL TreeIdSolver_RNE returned an error\n", file.c_str());
      std::abort();
    }
    for (int i = 0; i < n; ++i) t[index[i]] = kt[i];
    return t;
  };
  const auto Q = refdyn_bench::random_states(n, kStates, 3.0, 7000 + n);
  const auto QD = refdyn_bench::random_states(n, kStates, 2.0, 7001 + n);
  const auto QDD = refdyn_bench::random_states(n, kStates, 5.0, 7002 + n);
  Agreement agree{file, tol};
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < kStates; ++k) {
    const Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(Q.data() + k * n, n),
                          qd = Eigen::Map<const Eigen::VectorXd>(QD.data() + k * n, n),
                          qdd = Eigen::Map<const Eigen::VectorXd>(QDD.data() + k * n, n);
    const Eigen::VectorXd g = kdl_tau(q, zero, zero);
    Eigen::MatrixXd M(n, n);
    for (int j = 0; j < n; ++j) M.col(j) = kdl_tau(q, zero, Eigen::VectorXd::Unit(n, j)) - g;
    agree.expect("M: refdyn vs KDL (kdl_parser, TreeIdSolver_RNE)", k, refdyn::mass_matrix(m, data, q), M);
    agree.expect("g: refdyn vs KDL (kdl_parser, TreeIdSolver_RNE)", k, refdyn::gravity_forces(m, data, q), g);
    agree.expect("c+g: refdyn vs KDL (kdl_parser, TreeIdSolver_RNE)", k, refdyn::bias_forces(m, data, q, qd),
                 kdl_tau(q, qd, zero));
    agree.expect("tau: refdyn vs KDL (kdl_parser, TreeIdSolver_RNE)", k,
                 refdyn::inverse_dynamics(m, data, q, qd, qdd), kdl_tau(q, qd, qdd));
  }
  std::printf("check %-14s %2d DOF: refdyn's URDF loader and KDL's kdl_parser + TreeIdSolver_RNE agree (worst %.1e)\n",
              file.c_str(), n, agree.worst);
  return agree.ok;
}

// ---------------------------------------------------------------------------------------------
// Timed loops.

template <typename F>
void timed(benchmark::State& st, F&& f) {
  unsigned k = 0;
  for (auto _ : st) {
    f(static_cast<int>(k++ % kStates));
    benchmark::ClobberMemory();
  }
}

const std::vector<std::string> kQuantities = {"M", "c+g", "g", "ID"};

/// FD and CFD benchmarks of one case (`reg` registers one timed loop).
template <typename Reg>
void register_forward_dynamics(Case* c, Reg reg) {
  const std::string p = c->name + "/";
  refdyn::Data* d = c->data.get();
  const refdyn::Model* m = &c->model;
  KdlPeer* kdl = c->kdl.get();
  // Forward dynamics.
  reg(p + "FD/crba", [=](int k) {
    benchmark::DoNotOptimize(refdyn::forward_dynamics_crba(*m, *d, c->q[k], c->qd[k], c->tau[k]).data());
  });
  reg(p + "FD/aba", [=](int k) {
    benchmark::DoNotOptimize(refdyn::forward_dynamics_aba(*m, *d, c->q[k], c->qd[k], c->tau[k]).data());
  });
  reg(p + "FD/fused", [=](int k) {  // what the closed-loop plant does when its controller needs M, c + g
    refdyn::unchecked::mass_matrix_and_bias(*m, *d, c->q[k], c->qd[k]);
    d->ddq = c->tau[k] - d->nle;
    benchmark::DoNotOptimize(refdyn::unchecked::solve_mass_matrix(*d, d->ddq));
  });
  reg(p + "FD/auto", [=](int k) {
    benchmark::DoNotOptimize(refdyn::forward_dynamics(*m, *d, c->q[k], c->qd[k], c->tau[k]).data());
  });
  reg(p + "FD/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->forward_dynamics(k)); });
  MujocoPeer* mj = c->mujoco.get();
  reg(p + "FD/mujoco", [=](int k) { mj->time_forward_dynamics(k); });
  if (!c->constrained) return;
  // Constrained forward dynamics: one reference-dynamics evaluation.
  reg(p + "CFD/projection", [=](int k) {
    c->rd_proj->derivative(0.0, c->x[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  reg(p + "CFD/lagrange", [=](int k) {
    c->rd_lag->derivative(0.0, c->x[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  reg(p + "CFD/auto", [=](int k) {
    c->rd_auto->derivative(0.0, c->x[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  reg(p + "CFD/kdl_kkt", [=](int k) { benchmark::DoNotOptimize(kdl->constrained_forward_dynamics(k)); });
  if (!c->tip) return;
  // The tip held (3 rows): refdyn's routes, KDL's own constrained solver and the KKT peer.
  reg(p + "CFDtip/projection", [=](int k) {
    c->rd_tip_proj->derivative(0.0, c->x_tip[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  reg(p + "CFDtip/lagrange", [=](int k) {
    c->rd_tip_lag->derivative(0.0, c->x_tip[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  reg(p + "CFDtip/auto", [=](int k) {
    c->rd_tip_auto->derivative(0.0, c->x_tip[k], c->xdot);
    benchmark::DoNotOptimize(c->xdot.data());
  });
  KdlPeer* kt = c->kdl_tip.get();
  reg(p + "CFDtip/kdl_vereshchagin", [=](int k) { benchmark::DoNotOptimize(kt->vereshchagin(k)); });
  reg(p + "CFDtip/kdl_kkt", [=](int k) { benchmark::DoNotOptimize(kt->constrained_forward_dynamics(k)); });
}

void register_case(Case* c) {
  const std::string p = c->name + "/";
  refdyn::Data* d = c->data.get();
  const refdyn::Model* m = &c->model;
  KdlPeer* kdl = c->kdl.get();
  auto reg = [](const std::string& name, auto fn) {
    benchmark::RegisterBenchmark(name.c_str(), [fn](benchmark::State& st) { timed(st, fn); })
        ->Unit(benchmark::kNanosecond)
        ->ComputeStatistics("min", [](const std::vector<double>& v) {
          return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
        });
  };
  register_forward_dynamics(c, reg);
  if (c->crossover_only) return;
  // Joint-space mass matrix.
  reg(p + "M/recursive", [=](int k) { benchmark::DoNotOptimize(refdyn::mass_matrix(*m, *d, c->q[k]).data()); });
  reg(p + "M/trace", [=](int k) { benchmark::DoNotOptimize(refdyn::trace_mass_matrix(*m, *d, c->q[k]).data()); });
  reg(p + "M/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->mass_matrix(k)); });
  MujocoPeer* mj = c->mujoco.get();
  reg(p + "M/mujoco", [=](int k) { mj->time_mass_matrix(k); });
  // Bias forces c + g.
  reg(p + "c+g/recursive", [=](int k) {
    benchmark::DoNotOptimize(refdyn::bias_forces(*m, *d, c->q[k], c->qd[k]).data());
  });
  reg(p + "c+g/trace", [=](int k) {
    benchmark::DoNotOptimize(refdyn::trace_coriolis(*m, *d, c->q[k], c->qd[k]).data());
    benchmark::DoNotOptimize(refdyn::trace_gravity(*m, *d, c->q[k]).data());
  });
  reg(p + "c+g/kdl", [=](int k) {
    benchmark::DoNotOptimize(kdl->coriolis(k));
    benchmark::DoNotOptimize(kdl->gravity(k));
  });
  reg(p + "c+g/mujoco", [=](int k) { mj->time_bias_forces(k); });
  // Gravity alone (MuJoCo has no routine for it).
  reg(p + "g/recursive", [=](int k) { benchmark::DoNotOptimize(refdyn::gravity_forces(*m, *d, c->q[k]).data()); });
  reg(p + "g/trace", [=](int k) { benchmark::DoNotOptimize(refdyn::trace_gravity(*m, *d, c->q[k]).data()); });
  reg(p + "g/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->gravity(k)); });
  // Inverse dynamics (no trace-route counterpart).
  reg(p + "ID/recursive", [=](int k) {
    benchmark::DoNotOptimize(refdyn::inverse_dynamics(*m, *d, c->q[k], c->qd[k], c->qdd[k]).data());
  });
  reg(p + "ID/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->inverse_dynamics(k)); });
  reg(p + "ID/mujoco", [=](int k) { mj->time_inverse_dynamics(k); });
}

// ---------------------------------------------------------------------------------------------
// Reporting: the console shows the median and min aggregates; every repetition is collected
// for the final ratio table.

using refdyn_bench::fmt_ns;
using refdyn_bench::fmt_ratio;
using refdyn_bench::Reporter;
using refdyn_bench::Stats;

void print_ratio_table(const std::vector<std::unique_ptr<Case>>& cases, const Reporter& rep) {
  auto get = [&](const std::string& key) -> const Stats* {
    auto it = rep.stats.find(key);
    return it == rep.stats.end() ? nullptr : &it->second;
  };
  // The KDL routine behind each peer figure.
  const std::map<std::string, std::string> kdl_routine = {
      {"M", "ChainDynParam::JntToMass"},
      {"c+g", "ChainDynParam::JntToCoriolis + JntToGravity"},
      {"g", "ChainDynParam::JntToGravity"},
      {"ID", "ChainIdSolver_RNE::CartToJnt"},
      {"FD/kdl", "ChainFdSolver_RNE::CartToJnt (KDL's FD solver)"},
      {"CFD/kdl_kkt", "JntToMass + JntToCoriolis + JntToGravity + Eigen KKT written for this bench (KDL has no solver for a joint coupling)"},
      {"CFDtip/kdl_vereshchagin", "ChainHdSolver_Vereshchagin::CartToJnt (KDL's constrained solver)"},
      {"CFDtip/kdl_kkt", "JntToMass + JntToCoriolis + JntToGravity + Eigen KKT written for this bench"},
  };
  std::printf("\nRatios KDL / refdyn recursive, MuJoCo / recursive and trace / recursive (> 1: refdyn's recursive route\n");
  std::printf("is faster).\n");
  std::printf("Times are CPU time per call; 'med' = median over repetitions, 'min' = fastest repetition;\n");
  std::printf("ratios are med/med and min/min.\n\n");
  std::printf("| model | DOF | quantity | KDL routine | recursive med | recursive min | KDL med | KDL min | KDL/rec med | KDL/rec min | MuJoCo med | MuJoCo/rec med | MuJoCo/rec min | trace med | trace/rec med |\n");
  std::printf("|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& c : cases)
    for (const auto& qty : kQuantities) {
      const std::string p = c->name + "/" + qty + "/";
      const Stats* r = get(p + "recursive");
      const Stats* k = get(p + "kdl");
      const Stats* t = get(p + "trace");
      const Stats* mj = get(p + "mujoco");
      if (!r && !k && !t) continue;
      const double rm = r ? r->median() : NAN, rn = r ? r->min() : NAN;
      const double km = k ? k->median() : NAN, kn = k ? k->min() : NAN;
      const double mm = mj ? mj->median() : NAN, mn = mj ? mj->min() : NAN;
      const double tm = t ? t->median() : NAN;
      std::printf("| %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", c->name.c_str(),
                  c->model.nq, qty.c_str(), kdl_routine.at(qty).c_str(), fmt_ns(rm).c_str(), fmt_ns(rn).c_str(),
                  fmt_ns(km).c_str(), fmt_ns(kn).c_str(), fmt_ratio(km / rm).c_str(), fmt_ratio(kn / rn).c_str(),
                  fmt_ns(mm).c_str(), fmt_ratio(mm / rm).c_str(), fmt_ratio(mn / rn).c_str(), fmt_ns(tm).c_str(),
                  fmt_ratio(tm / rm).c_str());
    }
  std::printf("\nM = mass matrix (refdyn mass_matrix [CRBA] | trace_mass_matrix | KDL ChainDynParam::JntToMass)\n");
  std::printf("c+g = bias forces (bias_forces [RNEA, qdd = 0] | trace_coriolis + trace_gravity |\n");
  std::printf("      JntToCoriolis + JntToGravity)\n");
  std::printf("g = gravity (gravity_forces | trace_gravity | JntToGravity)\n");
  std::printf("ID = inverse dynamics (inverse_dynamics [RNEA] | - | ChainIdSolver_RNE::CartToJnt)\n");
  std::printf("MuJoCo (every call starts from qpos, qvel: mj_kinematics + mj_comPos, then) M: mj_crb + mj_fullM;\n");
  std::printf("c+g: mj_comVel + mj_rne(flg_acc = 0); ID: mj_comVel + mj_rne(flg_acc = 1); FD: mj_crb + mj_factorM +\n");
  std::printf("mj_comVel + mj_rne(0) + mj_solveM. MuJoCo has no gravity-only routine.\n");

  std::printf("\nForward dynamics (FD) and constrained forward dynamics (CFD: tip x, y, z + a joint coupling, 4 rows;\n");
  std::printf("CFDtip: the tip frame's origin held, 3 rows). FD: crba = forward_dynamics_crba (CRBA + RNEA + Cholesky),\n");
  std::printf("aba = forward_dynamics_aba, auto = forward_dynamics. CFD, CFDtip: crba = projection, aba = lagrange (KKT),\n");
  std::printf("auto = ReferenceSolver::Automatic. The KDL column names the routine it times (one row per peer).\n");
  std::printf("Medians; ratios med/med, the last min/min.\n\n");
  std::printf("fused = unchecked::mass_matrix_and_bias + solve_mass_matrix (the closed-loop plant's CRBA route).\n\n");
  std::printf("| model | DOF | quantity | crba/projection | fused | aba/lagrange | auto | KDL routine | KDL | crba÷aba (proj÷lag) | fused÷aba | KDL÷auto | KDL min÷auto min | MuJoCo | MuJoCo÷auto |\n");
  std::printf("|---|---:|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|\n");
  const std::vector<std::pair<std::string, std::string>> rows = {
      {"FD", "kdl"}, {"CFD", "kdl_kkt"}, {"CFDtip", "kdl_vereshchagin"}, {"CFDtip", "kdl_kkt"}};
  for (const auto& c : cases)
    for (const auto& [qty, peer] : rows) {
      const std::string p = c->name + "/" + qty + "/";
      const Stats* a = get(p + (qty == "FD" ? "crba" : "projection"));
      const Stats* b = get(p + (qty == "FD" ? "aba" : "lagrange"));
      const Stats* au = get(p + "auto");
      const Stats* k = get(p + peer);
      const Stats* fu = get(p + "fused");
      const Stats* mj = qty == "FD" && peer == "kdl" ? get(p + "mujoco") : nullptr;
      if (!a || !b || !au || !k) continue;
      const double fm = fu ? fu->median() : NAN;
      const double mm = mj ? mj->median() : NAN;
      std::printf("| %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", c->name.c_str(), c->model.nq,
                  qty.c_str(), fmt_ns(a->median()).c_str(), fmt_ns(fm).c_str(), fmt_ns(b->median()).c_str(),
                  fmt_ns(au->median()).c_str(), kdl_routine.at(qty + "/" + peer).c_str(), fmt_ns(k->median()).c_str(),
                  fmt_ratio(a->median() / b->median()).c_str(), fmt_ratio(fm / b->median()).c_str(),
                  fmt_ratio(k->median() / au->median()).c_str(), fmt_ratio(k->min() / au->min()).c_str(),
                  fmt_ns(mm).c_str(), fmt_ratio(mm / au->median()).c_str());
    }
}

int run(int argc, char** argv) {
  // Defaults (overridable on the command line, later flags win): interleaved repetitions.
  // --check-only: the start-up agreement check alone (CTest dynamics_bench_check).
  bool check_only = false;
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--check-only") {
      check_only = true;
      for (int j = i; j + 1 < argc; ++j) argv[j] = argv[j + 1];
      --argc;
      break;
    }
  if (!refdyn_bench::initialize_with_defaults(argc, argv)) return 1;

  std::vector<std::unique_ptr<Case>> cases;
  cases.push_back(make_case(refdyn_bench::paper_table(), refdyn::models::paper_manipulator(), 101));
  for (int dof : {7, 15, 30, 60}) {
    const DHTable t = refdyn_bench::random_table(dof, 1000 + dof);
    cases.push_back(make_case(t, model_from_table(t), 2000 + dof, /*tip=*/true));
  }
  // Extra sizes for the crossovers (FD and CFD only): kAbaFrom, kLagrangeFrom.
  for (int dof : {2, 4, 5, 6, 10, 20, 24}) {
    const DHTable t = refdyn_bench::random_table(dof, 1000 + dof);
    cases.push_back(make_case(t, model_from_table(t), 2000 + dof));
    cases.back()->crossover_only = true;
  }

  // Armature (KDL's joint inertia) on every joint of a chain and a tree of 3, 7 and 12 joints:
  // checked against KDL like the others (M, τ, FD, CFD with Vereshchagin), not timed.
  for (int dof : {3, 7, 12}) {
    DHTable t = refdyn_bench::random_table(dof, 4000 + dof);
    t.name = "rotor" + std::to_string(dof);
    for (size_t i = 0; i < t.links.size(); ++i) t.links[i].armature = 0.05 + 0.4 * static_cast<double>(i % 4);
    cases.push_back(make_case(t, model_from_table(t), 5000 + dof, /*tip=*/dof >= 7));
    cases.back()->check_only = true;
  }

  bool ok = true;
  for (auto& c : cases) ok = check_case(*c, 1e-10) && ok;
  // Robot descriptions in the shape real ones have (rounded π, fixed and continuous joints,
  // inertial origins with rpy, a hand with a mimic finger; the description package
  // tests/data/urdf/refdyn_test_arm). kdl_parser warns that it drops the root link's inertia:
  // the root is fixed to the world, so that inertia moves nothing.
  for (const char* urdf : {"examples/urdf/arm7.urdf", "tests/data/urdf/refdyn_test_arm/urdf/arm6.urdf",
                           "tests/data/urdf/refdyn_test_arm/urdf/arm7_hand.urdf"})
    ok = check_urdf(std::string(REFDYN_SOURCE_DIR_PATH) + "/" + urdf, 1e-10) && ok;
  if (!ok) {
    std::fprintf(stderr, "FATAL: refdyn and KDL disagree: the timings would not compare the same quantities. "
                         "Aborting.\n");
    std::abort();
  }
  std::printf("\n");
  std::fflush(stdout);

  if (check_only) return 0;
  for (auto& c : cases)
    if (!c->check_only) register_case(c.get());
  Reporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  print_ratio_table(cases, reporter);
  benchmark::Shutdown();
  return 0;
}

}  // namespace

// A model a peer cannot load (a URDF file missing, MuJoCo refusing an MJCF) ends the run with
// its message and exit code 2, not std::terminate.
int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "FATAL: %s\n", e.what());
    return 2;
  }
}
