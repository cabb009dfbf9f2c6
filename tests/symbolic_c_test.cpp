// The generated C (refdyn generate --format c, compiled at build time by tests/CMakeLists.txt)
// of six examples (planar_2r_circle fully constrained: n = m; waiter_tray with an acceleration
// row, p = 2) and of tests/data/symbolic/every_kind.yaml
// (the kinds and model features the examples leave out), armature.yaml (joint armature, one
// of them a symbol) and urdf_hand.yaml (a URDF hand: Drake rotor tags, a mimic finger, rounded π)
// against the numeric
// engine at random states: M, c, g, Q, ż, Φ, Φ̇, A, γ and ẋ of the reference dynamics. Two
// independent routes: the generator's symbolic Newton–Euler in body frames with
// GiNaC-differentiated constraint formulas, the engine's
// spatial-algebra RNEA/CRBA with analytic point kinematics and its own constraint code.
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/jerk.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include "arm_jerk/reference_dynamics.h"
#include "armature/reference_dynamics.h"
#include "urdf_hand/reference_dynamics.h"
#include "every_kind/reference_dynamics.h"
#include "mixed_jerk/reference_dynamics.h"
#include "mixed_jerk_t/reference_dynamics.h"
#include "four_bar/reference_dynamics.h"
#include "paper/reference_dynamics.h"
#include "planar_2r_circle/reference_dynamics.h"
#include "unicycle/reference_dynamics.h"
#include "urdf_arm_line/reference_dynamics.h"
#include "waiter_tray/reference_dynamics.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <string>
#include <vector>

namespace refdyn {
namespace {

/// The generated functions of one example, through a common interface.
struct Generated {
  std::string example;
  int nq, nz, nc;
  std::function<void(double, const double*, double*, double*, double*, double*, double*, double*, double*, double*,
                     double*, double*)>
      all;  // t, x → M, c, g, Q, zdot, phi, phid, A, gamma (and xdot, returns via last)
  std::function<int(double, const double*, double*)> rhs;
};

#define REFDYN_GENERATED(P, name)                                                                              \
  Generated{name, P##NQ, P##NZ, P##NC,                                                                         \
            [](double t, const double* x, double* M, double* c, double* g, double* Q, double* zd, double* phi,  \
               double* phid, double* A, double* gamma, double*) {                                              \
              P##params p;                                                                                     \
              P##default_params(&p);                                                                           \
              P##mass(x, &p, M);                                                                               \
              P##bias(x, &p, c, g);                                                                            \
              P##forces(t, x, &p, Q, zd);                                                                      \
              P##constraints(t, x, &p, phi, phid, A, gamma);                                                   \
            },                                                                                                 \
            [](double t, const double* x, double* xdot) {                                                      \
              P##params p;                                                                                     \
              P##default_params(&p);                                                                           \
              return P##rhs(t, x, &p, xdot);                                                                   \
            }}

// The macros of the headers carry the upper-case prefix, the functions the lower-case one.
#define paper_NQ PAPER_NQ
#define paper_NZ PAPER_NZ
#define paper_NC PAPER_NC
#define four_bar_NQ FOUR_BAR_NQ
#define four_bar_NZ FOUR_BAR_NZ
#define four_bar_NC FOUR_BAR_NC
#define unicycle_NQ UNICYCLE_NQ
#define unicycle_NZ UNICYCLE_NZ
#define unicycle_NC UNICYCLE_NC
#define planar_2r_circle_NQ PLANAR_2R_CIRCLE_NQ
#define planar_2r_circle_NZ PLANAR_2R_CIRCLE_NZ
#define planar_2r_circle_NC PLANAR_2R_CIRCLE_NC
#define every_kind_NQ EVERY_KIND_NQ
#define every_kind_NZ EVERY_KIND_NZ
#define every_kind_NC EVERY_KIND_NC
#define waiter_tray_NQ WAITER_TRAY_NQ
#define waiter_tray_NZ WAITER_TRAY_NZ
#define waiter_tray_NC WAITER_TRAY_NC
#define armature_NQ ARMATURE_NQ
#define armature_NZ ARMATURE_NZ
#define armature_NC ARMATURE_NC
#define urdf_hand_NQ URDF_HAND_NQ
#define urdf_hand_NZ URDF_HAND_NZ
#define urdf_hand_NC URDF_HAND_NC
#define arm_NQ ARM_NQ
#define arm_NZ ARM_NZ
#define arm_NC ARM_NC

std::vector<Generated> all_generated() {
  return {REFDYN_GENERATED(paper_, "paper"), REFDYN_GENERATED(four_bar_, "four_bar"),
          REFDYN_GENERATED(unicycle_, "unicycle"), REFDYN_GENERATED(arm_, "urdf_arm_line"),
          REFDYN_GENERATED(planar_2r_circle_, "planar_2r_circle"), REFDYN_GENERATED(every_kind_, "every_kind"),
          REFDYN_GENERATED(waiter_tray_, "waiter_tray"), REFDYN_GENERATED(armature_, "armature"),
          REFDYN_GENERATED(urdf_hand_, "urdf_hand")};
}

/// max |a − b| / max(1, max |b|)
double rel(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.size() == 0) return 0.0;
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

TEST(GeneratedC, EqualsTheEngineAtRandomStates) {
  for (const Generated& G : all_generated()) {
    SCOPED_TRACE(G.example);
    const std::string file = G.example == "every_kind" || G.example == "armature" || G.example == "urdf_hand"
                                 ? std::string(REFDYN_SOURCE_DIR) + "/tests/data/symbolic/" + G.example + ".yaml"
                                 : std::string(REFDYN_SOURCE_DIR) + "/examples/" + G.example + "/" + G.example + ".yaml";
    const auto problem = io::load_problem(file);
    const Model& model = problem->model;
    const int n = model.nq, m = problem->constraints.rows(), nz = problem->forces.num_states();
    ASSERT_EQ(G.nq, n);
    ASSERT_EQ(G.nz, nz);
    ASSERT_EQ(G.nc, m);
    auto rd = problem->make_reference_dynamics();
    Data data(model);
    ConstraintEval ev(model, problem->constraints);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    double worst_dyn = 0, worst_con = 0, worst_rhs = 0;
    for (int trial = 0; trial < 40; ++trial) {
      // Even trials: anywhere (±1 rad or m about q0) for M, c, g, Q, ż and the constraints; odd
      // trials: near q0 (±0.05), where the partition's K_dc is well conditioned, also for ẋ.
      const bool near = trial % 2 == 1;
      Eigen::VectorXd q = problem->q0, qd(n), z(nz);
      for (int i = 0; i < n; ++i) {
        q[i] += (near ? 0.05 : 1.0) * U(rng);
        qd[i] = (near ? 0.5 : 2.0) * U(rng);
      }
      for (int k = 0; k < nz; ++k) z[k] = 1e-3 * U(rng);
      const double t = problem->integrator.t0 + (problem->integrator.t1 - problem->integrator.t0) * 0.5 * (1 + U(rng));
      Eigen::VectorXd x(2 * n + nz);
      x << q, qd, z;

      // generated
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> M(n, n), A(std::max(m, 1), n);
      Eigen::VectorXd c(n), g(n), Q(n), zd(std::max(nz, 1)), phi(std::max(m, 1)), phid(std::max(m, 1)),
          gamma(std::max(m, 1)), xdot(x.size());
      G.all(t, x.data(), M.data(), c.data(), g.data(), Q.data(), zd.data(), phi.data(), phid.data(), A.data(),
            gamma.data(), nullptr);
      const int singular = G.rhs(t, x.data(), xdot.data());

      // engine
      const Eigen::MatrixXd M_e = mass_matrix(model, data, q);
      const Eigen::VectorXd g_e = gravity_forces(model, data, q);
      const Eigen::VectorXd c_e = bias_forces(model, data, q, qd) - g_e;
      Eigen::VectorXd Q_e(n), zd_e(std::max(nz, 1));
      problem->forces.evaluate(t, q, qd, z.data(), Q_e, zd_e.data());
      worst_dyn = std::max({worst_dyn, rel(M, M_e), rel(c, c_e), rel(g, g_e), rel(Q, Q_e),
                            nz ? rel(zd.head(nz), zd_e.head(nz)) : 0.0});
      if (m > 0) {
        evaluate_constraints(model, data, problem->constraints, ev, t, q, qd);
        worst_con = std::max({worst_con, rel(phi.head(m), ev.phi), rel(phid.head(m), ev.phid),
                              rel(A.topRows(m), ev.A), rel(gamma.head(m), ev.gamma)});
      }
      if (near) {
        ASSERT_EQ(singular, 0);
        Eigen::VectorXd xdot_e(x.size());
        rd->derivative(t, x, xdot_e);
        worst_rhs = std::max(worst_rhs, rel(xdot, xdot_e));
      }
    }
    EXPECT_LT(worst_dyn, 1e-12) << "M, c, g, Q, zdot";
    EXPECT_LT(worst_con, 1e-12) << "phi, phid, A, gamma";
    EXPECT_LT(worst_rhs, 1e-12) << "xdot";
    std::printf("%-14s n = %d, m = %d: max rel. difference M/c/g/Q %.1e, constraints %.1e, xdot %.1e\n",
                G.example.c_str(), n, m, worst_dyn, worst_con, worst_rhs);
  }
}


/// The generated functions of a jerk problem (state x = [q, q̇, q̈, z]).
struct GeneratedJerk {
  std::string file;
  bool engine_rhs;  ///< compare b and ẋ with JerkDynamics (else: b with a central difference only)
  int nq, nz, nc, nx;
  double kappa;  ///< the default of PREFIX_params::rd_kappa
  std::function<void(double, const double*, double*, double*, double*, double*, double*, double*, double*, double*,
                     double*, double*, double*, double*, double*, double*, double*)>
      all;  // t, x → M, c, g, Q, zdot, phi, phid, A, gamma, R, Rdot, G, Gdot, b
  std::function<int(double, const double*, double*)> rhs;
};

#define REFDYN_GENERATED_JERK(P, U, file, engine_rhs)                                                           \
  GeneratedJerk{file, engine_rhs, U##NQ, U##NZ, U##NC, U##NX,                                                               \
                [] {                                                                                           \
                  P##params p;                                                                                 \
                  P##default_params(&p);                                                                       \
                  return p.rd_kappa;                                                                           \
                }(),                                                                                           \
                [](double t, const double* x, double* M, double* c, double* g, double* Q, double* zd, double* phi, \
                   double* phid, double* A, double* gamma, double* R, double* Rdot, double* G, double* Gdot,   \
                   double* b, double*) {                                                                       \
                  P##params p;                                                                                 \
                  P##default_params(&p);                                                                       \
                  P##mass(x, &p, M);                                                                           \
                  P##bias(x, &p, c, g);                                                                        \
                  P##forces(t, x, &p, Q, zd);                                                                  \
                  P##constraints(t, x, &p, phi, phid, A, gamma);                                               \
                  P##jerk(t, x, &p, R, Rdot, G, Gdot, b);                                                      \
                },                                                                                             \
                [](double t, const double* x, double* xdot) {                                                  \
                  P##params p;                                                                                 \
                  P##default_params(&p);                                                                       \
                  return P##rhs(t, x, &p, xdot);                                                               \
                }}

/// The generated C of jerk problems against JerkDynamics at random states: M, c, g, Q, ż, G (A
/// of the rows of order ≤ 2, B of the jerk rows), the jerk level's right-hand sides b (the
/// engine's −s: −s for a jerk row, −ψ̇|q⃛=0 − κψ for a lower row), R = M q̈ + c + g − Q and
/// ẋ = [q̇, q̈, q⃛, ż]. arm_jerk: jerk rows only (2R arm, forces with rates); mixed_jerk: a
/// holonomic row and a differentiated jerk row on a 3-link arm, with a LuGre state. For every
/// row of order ≤ 2 also b = −ψ̇ − κψ against a central difference of the generated ψ along the
/// motion (q⃛ = 0) — an independent check of the rates, also for mixed_jerk_t's rheonomic row
/// (whose ∂/∂t the engine takes with time as a dual number).
TEST(GeneratedC, JerkProblemsEqualJerkDynamics) {
  for (const GeneratedJerk& G : {REFDYN_GENERATED_JERK(arm_jerk_, ARM_JERK_, "arm_jerk", true),
                                 REFDYN_GENERATED_JERK(mixed_jerk_, MIXED_JERK_, "mixed_jerk", true),
                                 REFDYN_GENERATED_JERK(mixed_jerk_t_, MIXED_JERK_T_, "mixed_jerk_t", true)}) {
    SCOPED_TRACE(G.file);
    const auto problem = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/tests/data/symbolic/" + G.file + ".yaml");
    ASSERT_TRUE(problem->is_jerk_problem());
    const Model& model = problem->model;
    const int n = model.nq, m = problem->constraints.rows(), nz = problem->forces.num_states();
    ASSERT_EQ(G.nq, n);
    ASSERT_EQ(G.nc, m);
    ASSERT_EQ(G.nz, nz);
    ASSERT_EQ(G.nx, 3 * n + nz);
    EXPECT_EQ(G.kappa, problem->kappa);  // baumgarte.kappa of the scenario
    JerkDynamics jd(model, problem->constraints, problem->jerk_options(), &problem->forces);
    Data data(model);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    double worst_dyn = 0, worst_row = 0, worst_R = 0, worst_rhs = 0, worst_qddd = 0, worst_fd = 0;
    for (int trial = 0; trial < 40; ++trial) {
      Eigen::VectorXd q = problem->q0, qd(n), qdd(n), z(nz);
      for (int i = 0; i < n; ++i) {
        q[i] += 0.3 * U(rng);
        qd[i] = 1.0 * U(rng);
        qdd[i] = 3.0 * U(rng);
      }
      for (int k = 0; k < nz; ++k) z[k] = 1e-3 * U(rng);
      const double t = 2.0 * 0.5 * (1 + U(rng));
      Eigen::VectorXd x(3 * n + nz);
      x << q, qd, qdd, z;
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> M(n, n), A(m, n), Gm(m, n), Gdot(m, n);
      Eigen::VectorXd c(n), g(n), Q(n), zd(std::max(nz, 1)), phi(m), phid(m), gamma(m), R(n), Rdot(n), b(m),
          xdot(x.size());
      G.all(t, x.data(), M.data(), c.data(), g.data(), Q.data(), zd.data(), phi.data(), phid.data(), A.data(),
            gamma.data(), R.data(), Rdot.data(), Gm.data(), Gdot.data(), b.data(), nullptr);
      ASSERT_EQ(G.rhs(t, x.data(), xdot.data()), 0);

      const Eigen::MatrixXd M_e = mass_matrix(model, data, q);
      const Eigen::VectorXd g_e = gravity_forces(model, data, q);
      const Eigen::VectorXd c_e = bias_forces(model, data, q, qd) - g_e;
      Eigen::VectorXd Q_e(n), zd_e(std::max(nz, 1));
      problem->forces.evaluate(t, q, qd, z.data(), Q_e, zd_e.data());
      worst_dyn = std::max({worst_dyn, rel(M, M_e), rel(c, c_e), rel(g, g_e), rel(Q, Q_e),
                            nz ? rel(zd.head(nz), zd_e.head(nz)) : 0.0});
      Eigen::VectorXd xdot_e(x.size());
      jd.derivative(t, x, xdot_e);
      worst_row = std::max(worst_row, rel(Gm, jd.B()));
      worst_R = std::max(worst_R, rel(R, jd.constraint_force()));
      if (G.engine_rhs) {
        worst_row = std::max(worst_row, rel(b, -jd.s()));
        worst_rhs = std::max(worst_rhs, rel(xdot, xdot_e));
        worst_qddd = std::max(worst_qddd, rel(xdot.segment(2 * n, n), xdot_e.segment(2 * n, n)));
      } else {  // the solve: G q⃛ = b
        worst_rhs = std::max(worst_rhs, rel(Gm * xdot.segment(2 * n, n), b));
        worst_rhs = std::max(worst_rhs, rel(xdot.head(2 * n), x.segment(n, 2 * n)));
      }
      // b of the rows of order ≤ 2 against −ψ̇ − κψ, ψ̇ by a central difference of the generated
      // ψ = A q̈ + γ (+ 2αΦ̇ + β²Φ, + β₁c) along the motion with q⃛ = 0
      auto psi = [&](double h) {
        Eigen::VectorXd xs = x;
        xs.head(n) += h * qd + 0.5 * h * h * qdd;
        xs.segment(n, n) += h * qdd;
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Ah(m, n);
        Eigen::VectorXd Mh(n * n), ch(n), gh(n), Qh(n), zh(std::max(nz, 1)), ph(m), pdh(m), gah(m), Rh(n), Rdh(n), Gh(m * n),
            Gdh(m * n), bh(m);
        G.all(t + h, xs.data(), Mh.data(), ch.data(), gh.data(), Qh.data(), zh.data(), ph.data(), pdh.data(), Ah.data(),
              gah.data(), Rh.data(), Rdh.data(), Gh.data(), Gdh.data(), bh.data(), nullptr);
        Eigen::VectorXd v = Ah * qdd + gah;
        const ReferenceDynamicsOptions& o = problem->options;
        for (int r = 0; r < m; ++r) {
          const int order = problem->constraints.row_order(r);
          if (order == 0) v[r] += 2 * o.alpha * pdh[r] + o.beta * o.beta * ph[r];
          if (order == 1) v[r] += o.beta_first_order * ph[r];
        }
        return v;
      };
      const double h = 1e-4;
      const Eigen::VectorXd psi0 = psi(0.0), psid = (psi(h) - psi(-h)) / (2 * h);
      for (int r = 0; r < m; ++r)
        if (problem->constraints.row_order(r) < 3) {
          const double expected = -psid[r] - problem->kappa * psi0[r];
          worst_fd = std::max(worst_fd, std::abs(b[r] - expected) / std::max(1.0, std::abs(expected)));
        }
    }
    EXPECT_LT(worst_dyn, 1e-12) << "M, c, g, Q, zdot";
    EXPECT_LT(worst_row, 1e-12) << "G, b";
    EXPECT_LT(worst_R, 1e-12) << "R";
    EXPECT_LT(worst_rhs, 1e-12) << "xdot";
    EXPECT_LT(worst_qddd, 1e-12) << "qddd";
    EXPECT_LT(worst_fd, 1e-6) << "b of the rows of order <= 2 against a central difference (h = 1e-4)";
    std::printf("%-14s n = %d, m = %d, nz = %d: max rel. difference M/c/g/Q/zdot %.1e, G%s %.1e, R %.1e, xdot %.1e "
                "(qddd %.1e)%s; lower rows' b vs central difference %.1e\n",
                G.file.c_str(), n, m, nz, worst_dyn, G.engine_rhs ? "/b" : "", worst_row, worst_R, worst_rhs, worst_qddd,
                G.engine_rhs ? "" : " [xdot: G qddd = b]", worst_fd);
  }
}

}  // namespace
}  // namespace refdyn
