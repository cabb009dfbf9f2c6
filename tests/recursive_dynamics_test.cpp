// Recursive dynamics (RNEA, CRBA, forward dynamics by CRBA + Cholesky and by the articulated-body
// algorithm, energies): algebraic identities on random chains and trees of 1..60 DOF, Lagrangian
// identities checked by finite differences, and closed-form oracles (planar 2R arm, pendulum,
// sliders).
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

using namespace refdyn;
using refdyn::test::near;

namespace {

struct Case {
  std::string label;
  Model model;
  ModelDescription desc;
};

const std::vector<int> kSizes = {1, 2, 3, 5, 8, 13, 21, 30};

/// For each size: a standard-DH chain, a modified-DH chain with fixed links, a tree, and a
/// tree with general joint axes (not only the DH z axis).
std::vector<Case> random_models(std::mt19937& rng, const std::vector<int>& sizes = kSizes) {
  std::vector<Case> out;
  for (auto& c : test::random_model_family(rng, sizes, test::randomize_axes, "tree, general axes +fixed"))
    out.push_back({c.label, build_model(c.desc), c.desc});
  return out;
}

double inf_norm(const Eigen::MatrixXd& a) { return a.cwiseAbs().maxCoeff(); }

/// Central difference of M along q̇: Ṁ = dM(q + t q̇)/dt at t = 0.
Eigen::MatrixXd mdot_fd(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double h) {
  Data d(model);
  const Eigen::MatrixXd Mp = mass_matrix(model, d, q + h * qd);
  const Eigen::MatrixXd Mm = mass_matrix(model, d, q - h * qd);
  return (Mp - Mm) / (2 * h);
}

constexpr double kH = 1e-5;       // central-difference step
constexpr double kFdTol = 1e-7;   // FD of M, V and T over chains up to 30 DOF (worst seen ~1e-9)

}  // namespace

// ---------------------------------------------------------------------------------------------
// Algebraic identities between the recursive algorithms

TEST(RecursiveDynamics, MassMatrixColumnsFromInverseDynamics) {
  std::mt19937 rng(101);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), z = Eigen::VectorXd::Zero(n);
    const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
    const Eigen::VectorXd tau0 = inverse_dynamics(c.model, data, q, z, z);
    // The subtraction cancels |g|; compare at the scale of max(|M|, |g|).
    const double scale = std::max(inf_norm(M), inf_norm(tau0));
    Eigen::MatrixXd Mid(n, n);
    for (int i = 0; i < n; ++i)
      Mid.col(i) = inverse_dynamics(c.model, data, q, z, Eigen::VectorXd::Unit(n, i)) - tau0;
    EXPECT_TRUE(near(M, Mid, 0, 1e-12 * scale)) << c.label;
  }
}

TEST(RecursiveDynamics, BiasAndGravityAreInverseDynamicsWithZeroArguments) {
  std::mt19937 rng(102);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          z = Eigen::VectorXd::Zero(n);
    const Eigen::VectorXd tau_v = inverse_dynamics(c.model, data, q, qd, z);
    const Eigen::VectorXd tau_0 = inverse_dynamics(c.model, data, q, z, z);
    EXPECT_TRUE(near(bias_forces(c.model, data, q, qd), tau_v, 1e-14)) << c.label;
    EXPECT_TRUE(near(gravity_forces(c.model, data, q), tau_0, 1e-14)) << c.label;
    // Linearity in q̈: ID(q, q̇, q̈) = M q̈ + c + g.
    const Eigen::VectorXd qdd = test::random_vector(rng, n, 2.0);
    const Eigen::VectorXd M_qdd = mass_matrix(c.model, data, q) * qdd;
    const Eigen::VectorXd tau = inverse_dynamics(c.model, data, q, qd, qdd);
    EXPECT_TRUE(near(tau, M_qdd + tau_v, 0, 1e-12 * std::max(inf_norm(M_qdd), inf_norm(tau_v)))) << c.label;
    // c is quadratic in q̇: c(2q̇) = 4 c(q̇).
    const Eigen::VectorXd c1 = bias_forces(c.model, data, q, qd) - tau_0;
    const Eigen::VectorXd c2 = bias_forces(c.model, data, q, 2 * qd) - tau_0;
    EXPECT_TRUE(near(c2, 4 * c1, 0, 1e-12 * std::max(inf_norm(c2), inf_norm(tau_0)))) << c.label;
  }
}

// The q̈ = 0 sweep behind bias_forces and unchecked::rnea(q, &q̇, nullptr, …) (the kernel's
// rnea_impl<true, false>: no acceleration terms, gravity as the base acceleration) against the
// full RNEA with q̈ = 0 given, with and without gravity, for chains and trees, DH (±z) and
// general axes, revolute and prismatic joints, sizes 1–30 (the four-joint sin/cos blocks,
// partial and whole): the torques and what the sweep leaves in data (joint placements, the body
// motions the constraint kinematics read after it, body forces).
TEST(RecursiveDynamics, BiasSweepEqualsInverseDynamicsWithZeroAcceleration) {
  std::mt19937 rng(111);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          z = Eigen::VectorXd::Zero(n);
    for (bool gravity : {true, false}) {
      Data d1(c.model), d2(c.model);
      Eigen::VectorXd tau_bias(n), tau_id(n);
      unchecked::rnea(c.model, d1, q, &qd, nullptr, gravity, tau_bias);
      unchecked::rnea(c.model, d2, q, &qd, &z, gravity, tau_id);
      const std::string label = c.label + (gravity ? ", gravity" : ", no gravity");
      EXPECT_TRUE(near(tau_bias, tau_id, 1e-12)) << label;
      if (gravity) {
        EXPECT_TRUE(near(bias_forces(c.model, d1, q, qd), tau_id, 1e-12)) << label;
      }
      double sv = 0, sa = 0, sf = 0;  // scales of the body quantities
      for (int i = 0; i < n; ++i) {
        sv = std::max({sv, d2.v[i].w.cwiseAbs().maxCoeff(), d2.v[i].v.cwiseAbs().maxCoeff()});
        sa = std::max({sa, d2.a[i].w.cwiseAbs().maxCoeff(), d2.a[i].v.cwiseAbs().maxCoeff()});
        sf = std::max({sf, d2.f[i].n.cwiseAbs().maxCoeff(), d2.f[i].f.cwiseAbs().maxCoeff()});
      }
      for (int i = 0; i < n; ++i) {
        EXPECT_EQ(d1.liMi[i].R, d2.liMi[i].R) << label << " body " << i;
        EXPECT_EQ(d1.liMi[i].p, d2.liMi[i].p) << label << " body " << i;
        EXPECT_TRUE(near(d1.v[i].w, d2.v[i].w, 0, 1e-12 * sv)) << label << " body " << i;
        EXPECT_TRUE(near(d1.v[i].v, d2.v[i].v, 0, 1e-12 * sv)) << label << " body " << i;
        EXPECT_TRUE(near(d1.a[i].w, d2.a[i].w, 0, 1e-12 * sa)) << label << " body " << i;
        EXPECT_TRUE(near(d1.a[i].v, d2.a[i].v, 0, 1e-12 * sa)) << label << " body " << i;
        EXPECT_TRUE(near(d1.f[i].n, d2.f[i].n, 0, 1e-12 * sf)) << label << " body " << i;
        EXPECT_TRUE(near(d1.f[i].f, d2.f[i].f, 0, 1e-12 * sf)) << label << " body " << i;
      }
    }
  }
}

// The fused sweep (small models) and the CRBA + RNEA fallback (larger ones) behind
// unchecked::mass_matrix_and_bias give what the separate public calls give, including the
// body velocities and accelerations the constraint kinematics read afterwards.
TEST(RecursiveDynamics, MassMatrixAndBiasTogetherEqualTheSeparateCalls) {
  std::mt19937 rng(109);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data d1(c.model), d2(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    const Eigen::MatrixXd M = mass_matrix(c.model, d1, q);
    const Eigen::VectorXd nle = bias_forces(c.model, d1, q, qd);
    d2.M.setConstant(std::nan(""));  // every entry must be written
    unchecked::mass_matrix_and_bias(c.model, d2, q, qd);
    EXPECT_TRUE(near(d2.M, M, 1e-14, 1e-14)) << c.label;
    EXPECT_TRUE(near(d2.nle, nle, 1e-14, 1e-14)) << c.label;
    for (int i = 0; i < n; ++i) {
      EXPECT_TRUE(near(d2.v[i].w, d1.v[i].w, 1e-14, 1e-14)) << c.label << " body " << i;
      EXPECT_TRUE(near(d2.v[i].v, d1.v[i].v, 1e-14, 1e-14)) << c.label << " body " << i;
      EXPECT_TRUE(near(d2.a[i].w, d1.a[i].w, 1e-14, 1e-14)) << c.label << " body " << i;
      EXPECT_TRUE(near(d2.a[i].v, d1.a[i].v, 1e-14, 1e-14)) << c.label << " body " << i;
    }
  }
}

TEST(RecursiveDynamics, SolveMassMatrixMatchesAnIndependentFactorization) {
  std::mt19937 rng(110);
  for (const Case& c : random_models(rng)) {  // sizes 1 .. 30: the fixed-size and the dynamic path
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), b = test::random_vector(rng, n, 2.0);
    const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
    Eigen::VectorXd x = b;
    ASSERT_TRUE(unchecked::solve_mass_matrix(data, x)) << c.label;
    const Eigen::VectorXd expected = M.fullPivLu().solve(b);
    EXPECT_TRUE(near(x, expected, 1e-9, 1e-12)) << c.label;
    EXPECT_TRUE(near(M * x, b, 1e-10, 1e-12)) << c.label;
    // Not positive definite: reported, not solved.
    data.M = -M;
    x = b;
    EXPECT_FALSE(unchecked::solve_mass_matrix(data, x)) << c.label;
  }
}

namespace {
using ForwardDynamicsFn = const Eigen::VectorXd& (*)(const Model&, Data&, const Eigen::VectorXd&,
                                                      const Eigen::VectorXd&, const Eigen::VectorXd&);

/// cond₂(M) of a symmetric positive definite matrix.
double condition(const Eigen::MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
  return es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
}

/// `fd` against RNEA on every case: the backward error of M q̈ + c + g = τ is at rounding level,
/// and τ from RNEA at a chosen q̈ gives that q̈ back to cond(M)·ε.
void expect_forward_dynamics_inverts_inverse_dynamics(const std::vector<Case>& cases, std::mt19937& rng,
                                                      ForwardDynamicsFn fd) {
  for (const Case& c : cases) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          tau = test::random_vector(rng, n, 20.0);
    const Eigen::VectorXd qdd = fd(c.model, data, q, qd, tau);
    EXPECT_TRUE(qdd.allFinite()) << c.label;
    // (the ABA route leaves no M or c + g in data: computed here)
    const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
    const Eigen::VectorXd nle = bias_forces(c.model, data, q, qd);
    // Backward error: the residual of M q̈ + c + g = τ is at rounding level.
    const Eigen::VectorXd tau_back = inverse_dynamics(c.model, data, q, qd, qdd);
    const double scale = std::max({inf_norm(tau), inf_norm(M * qdd), inf_norm(nle)});
    EXPECT_TRUE(near(tau_back, tau, 0, 1e-11 * scale)) << c.label;
    // Forward error, the other way round, bounded by cond(M)·ε.
    const Eigen::VectorXd qdd_ref = test::random_vector(rng, n, 2.0);
    const Eigen::VectorXd tau2 = inverse_dynamics(c.model, data, q, qd, qdd_ref);
    const Eigen::VectorXd qdd2 = fd(c.model, data, q, qd, tau2);
    const double cond = condition(M);
    EXPECT_LE(test::rel_diff(qdd2, qdd_ref), 1e-13 * cond + 1e-13) << c.label << " cond(M) = " << cond;
  }
}
}  // namespace

TEST(RecursiveDynamics, ForwardDynamicsInvertsInverseDynamics) {
  std::mt19937 rng(103);
  expect_forward_dynamics_inverts_inverse_dynamics(random_models(rng), rng, forward_dynamics);
}

// ---------------------------------------------------------------------------------------------
// Articulated-body algorithm: against CRBA + Cholesky (an independent route to the same q̈),
// against RNEA (its inverse), and the automatic choice between the two.

namespace {
/// The random models of every size in kSizes plus 45 and 60 bodies (chains and trees, DH and
/// general axes, fixed links folded); the general-axis variants get axes of non-unit length
/// (build_model normalizes them).
std::vector<Case> aba_models(std::mt19937& rng) {
  std::vector<Case> all = random_models(rng);
  for (Case& c : random_models(rng, {45, 60})) all.push_back(std::move(c));
  std::vector<Case> out;
  for (const Case& c : all) {
    if (c.label.find("general") == std::string::npos) {
      out.push_back(c);
      continue;
    }
    ModelDescription d = c.desc;
    for (std::size_t i = 0; i < d.links.size(); ++i) d.links[i].axis *= 0.25 + 0.5 * static_cast<double>(i % 5);
    out.push_back({c.label + ", non-unit axes", build_model(d), d});
  }
  return out;
}
}  // namespace

TEST(ArticulatedBody, EqualsCrbaCholesky) {
  std::mt19937 rng(120);
  for (const Case& c : aba_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    for (int rep = 0; rep < 3; ++rep) {
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                            tau = test::random_vector(rng, n, 20.0);
      const Eigen::VectorXd crba = forward_dynamics_crba(c.model, data, q, qd, tau);
      const Eigen::MatrixXd M = data.M;
      const Eigen::VectorXd aba = forward_dynamics_aba(c.model, data, q, qd, tau);
      // Both are backward stable: the two solutions differ by at most cond(M)·ε (relative).
      const double cond = condition(M);
      EXPECT_LE(test::rel_diff(aba, crba), 1e-13 * cond + 1e-13) << c.label << " cond(M) = " << cond;
      // The world poses ABA leaves in data are forward kinematics'.
      Data fk(c.model);
      forward_kinematics(c.model, fk, q);
      for (int i = 0; i < n; ++i) {
        EXPECT_TRUE(near(data.oMi[i].R, fk.oMi[i].R, 1e-14, 1e-14)) << c.label;
        EXPECT_TRUE(near(data.oMi[i].p, fk.oMi[i].p, 1e-13, 1e-13)) << c.label;
      }
    }
  }
}

TEST(ArticulatedBody, InverseDynamicsOfItsResultGivesTau) {
  std::mt19937 rng(121);
  const std::vector<Case> cases = aba_models(rng);
  expect_forward_dynamics_inverts_inverse_dynamics(cases, rng, forward_dynamics_aba);
  expect_forward_dynamics_inverts_inverse_dynamics(cases, rng, forward_dynamics_crba);
}

TEST(ArticulatedBody, SolveReusesTheFactorizationOfTheLastCall) {
  std::mt19937 rng(126);
  for (const Case& c : aba_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          tau = test::random_vector(rng, n, 20.0), b = test::random_vector(rng, n, 5.0);
    forward_dynamics_aba(c.model, data, q, qd, tau);
    Eigen::VectorXd x(n);
    unchecked::aba_solve(c.model, data, b.data(), x.data());
    const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
    const double cond = condition(M);
    EXPECT_LE(test::rel_diff(x, M.fullPivLu().solve(b)), 1e-13 * cond + 1e-13) << c.label << " cond(M) = " << cond;
    Eigen::VectorXd in_place = b;  // x may be tau
    unchecked::aba_solve(c.model, data, in_place.data(), in_place.data());
    EXPECT_EQ(in_place, x) << c.label;
  }
}

TEST(ArticulatedBody, UncheckedKernelEqualsCheckedFunction) {
  std::mt19937 rng(122);
  for (const Case& c : aba_models(rng)) {
    const int n = c.model.nq;
    Data d1(c.model), d2(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          tau = test::random_vector(rng, n, 20.0);
    Eigen::VectorXd out(n);
    ASSERT_EQ(unchecked::aba(c.model, d2, q, qd, tau, out), -1) << c.label;
    EXPECT_EQ(forward_dynamics_aba(c.model, d1, q, qd, tau), out) << c.label;  // bit for bit
    Eigen::VectorXd in_place = tau;  // the result may overwrite τ
    ASSERT_EQ(unchecked::aba(c.model, d2, q, qd, in_place, in_place), -1) << c.label;
    EXPECT_EQ(in_place, out) << c.label;
  }
}

TEST(ArticulatedBody, AutomaticForwardDynamicsIsExactlyTheChosenAlgorithm) {
  EXPECT_FALSE(forward_dynamics_uses_aba(1));
  EXPECT_FALSE(forward_dynamics_uses_aba(kAbaFrom - 1));
  EXPECT_TRUE(forward_dynamics_uses_aba(kAbaFrom));
  EXPECT_TRUE(forward_dynamics_uses_aba(60));
  std::mt19937 rng(123);
  for (const Case& c : aba_models(rng)) {
    const int n = c.model.nq;
    Data d1(c.model), d2(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          tau = test::random_vector(rng, n, 20.0);
    const Eigen::VectorXd automatic = forward_dynamics(c.model, d1, q, qd, tau);
    const Eigen::VectorXd chosen = forward_dynamics_uses_aba(n) ? forward_dynamics_aba(c.model, d2, q, qd, tau)
                                                                : forward_dynamics_crba(c.model, d2, q, qd, tau);
    EXPECT_EQ(automatic, chosen) << c.label;  // bit for bit
  }
}

TEST(ArticulatedBody, SingularMassMatrixIsAnErrorNamingTheJoint) {
  // A massless last link on a revolute joint whose axis passes through nothing: D = 0 there.
  for (int n : {1, 3, kAbaFrom, 40}) {
    std::mt19937 rng(124 + n);
    test::RandomChainOptions o;
    o.dof = n;
    o.prismatic_fraction = 0.0;
    ModelDescription d = test::random_chain(rng, o);
    d.links.back().inertia = LinkInertia{};
    d.links.back().joint_name = "ghost_joint";
    const Model model = build_model(d);
    Data data(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 1.0), z = Eigen::VectorXd::Zero(n);
    test::expect_error_mentioning([&] { forward_dynamics_aba(model, data, q, z, z); },
                                  {"not positive definite", "ghost_joint"});
    EXPECT_THROW(forward_dynamics(model, data, q, z, z), Error) << n;
    Eigen::VectorXd out(n);
    EXPECT_EQ(unchecked::aba(model, data, q, z, z, out), n - 1);
  }
  // Bad sizes and non-finite input: the checks of forward_dynamics.
  std::mt19937 rng(125);
  const Model model = build_model(test::random_chain(rng, {}));
  Data data(model);
  const Eigen::VectorXd ok = Eigen::VectorXd::Zero(model.nq);
  Eigen::VectorXd nan = ok;
  nan[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(forward_dynamics_aba(model, data, Eigen::VectorXd::Zero(model.nq + 1), ok, ok), Error);
  EXPECT_THROW(forward_dynamics_aba(model, data, ok, nan, ok), Error);
  EXPECT_THROW(forward_dynamics_aba(model, data, ok, ok, nan), Error);
  Data other(build_model(test::random_chain(rng, {})));
  EXPECT_THROW(forward_dynamics_aba(model, other, ok, ok, ok), Error);
}

TEST(RecursiveDynamics, MassMatrixIsSymmetricPositiveDefiniteAndEqualsTraceRoute) {
  std::mt19937 rng(104);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    for (int rep = 0; rep < 3; ++rep) {
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0);
      const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
      EXPECT_TRUE(near(M, M.transpose(), 0, 0)) << c.label;
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
      EXPECT_GT(es.eigenvalues().minCoeff(), 0.0) << c.label;
      EXPECT_TRUE(near(trace_mass_matrix(c.model, data, q), M, 1e-11)) << c.label;
      // ½ q̇ᵀ M q̇ is the kinetic energy, three ways.
      const Eigen::VectorXd qd = test::random_vector(rng, n, 2.0);
      const double T_M = 0.5 * qd.dot(M * qd);
      EXPECT_GT(T_M, 0.0);
      EXPECT_NEAR(kinetic_energy(c.model, data, q, qd), T_M, 1e-12 * T_M) << c.label;
      EXPECT_NEAR(trace_kinetic_energy(c.model, data, q, qd), T_M, 1e-11 * T_M) << c.label;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Lagrangian identities (finite differences in the test only)

TEST(RecursiveDynamics, CoriolisFromLagrangeEquations) {
  // From L = ½ q̇ᵀ M q̇ − V:  c = Ṁ q̇ − ∂T/∂q  and  g = ∂V/∂q.
  std::mt19937 rng(105);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model), d2(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    const Eigen::VectorXd g = gravity_forces(c.model, data, q);
    const Eigen::VectorXd cvec = bias_forces(c.model, data, q, qd) - g;
    Eigen::VectorXd dTdq(n), dVdq(n);
    for (int i = 0; i < n; ++i) {
      const Eigen::VectorXd e = Eigen::VectorXd::Unit(n, i);
      dTdq[i] = (kinetic_energy(c.model, d2, q + kH * e, qd) - kinetic_energy(c.model, d2, q - kH * e, qd)) / (2 * kH);
      dVdq[i] = (potential_energy(c.model, d2, q + kH * e) - potential_energy(c.model, d2, q - kH * e)) / (2 * kH);
    }
    const Eigen::VectorXd c_lagrange = mdot_fd(c.model, q, qd, kH) * qd - dTdq;
    const double cscale = inf_norm(mass_matrix(c.model, d2, q)) * qd.squaredNorm();
    EXPECT_TRUE(near(cvec, c_lagrange, kFdTol, kFdTol * cscale)) << c.label;
    // The FD of V carries rounding ~ε|V|/h; g itself sets the scale of the comparison.
    const double V = potential_energy(c.model, d2, q);
    EXPECT_TRUE(near(g, dVdq, kFdTol, kFdTol * (inf_norm(g) + std::abs(V)))) << c.label;
  }
}

TEST(RecursiveDynamics, SkewSymmetryOfMdotMinus2C) {
  // q̇ᵀ(Ṁ − 2C)q̇ = 0  ⇔  q̇ᵀ Ṁ q̇ = 2 q̇ᵀ c(q, q̇).
  std::mt19937 rng(106);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    const Eigen::VectorXd cvec = bias_forces(c.model, data, q, qd) - gravity_forces(c.model, data, q);
    const Eigen::MatrixXd Md = mdot_fd(c.model, q, qd, kH);
    mass_matrix(c.model, data, q);
    const double lhs = qd.dot(Md * qd), rhs = 2 * qd.dot(cvec);
    // Terms of size |Ṁ||q̇|²; the FD of M carries rounding ~ε|M|/h even where Ṁ = 0 (n = 1).
    const double scale = std::max(inf_norm(Md), inf_norm(data.M)) * qd.squaredNorm();
    EXPECT_NEAR(lhs, rhs, kFdTol * scale) << c.label << " (scale " << scale << ")";
  }
}

TEST(RecursiveDynamics, EnergiesAgreeWithTraceRoute) {
  std::mt19937 rng(107);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    const double T = kinetic_energy(c.model, data, q, qd), V = potential_energy(c.model, data, q);
    EXPECT_NEAR(trace_kinetic_energy(c.model, data, q, qd), T, 1e-11 * T) << c.label;
    // V is the sum of Σ m_l g·r_C terms of both signs; compare at the scale of the largest.
    double Vscale = 0;
    forward_kinematics(c.model, data, q);
    for (int l = 0; l < n; ++l) {
      const Inertia& I = c.model.inertia[static_cast<size_t>(l)];
      Vscale += std::abs(c.model.gravity.dot(data.oMi[l].R * I.h + I.m * data.oMi[l].p));
    }
    EXPECT_NEAR(trace_potential_energy(c.model, data, q), V, 1e-13 * Vscale) << c.label;
    // V from the point-mass definition: −Σ m gᵀ r_C with r_C from the reference kinematics.
    const std::vector<SE3> X = test::reference_link_poses(c.desc, q);
    double V_ref = 0;
    for (size_t k = 0; k < c.desc.links.size(); ++k) {
      const LinkSpec& l = c.desc.links[k];
      bool moves = false;  // links rigidly attached to the world are left out by the model
      for (int a = static_cast<int>(k); a >= 0; a = c.desc.links[static_cast<size_t>(a)].parent)
        moves = moves || c.desc.links[static_cast<size_t>(a)].type != JointType::Fixed;
      if (moves) V_ref -= l.inertia.mass * c.model.gravity.dot(X[k].act_point(l.inertia.com));
    }
    EXPECT_NEAR(V_ref, V, 1e-13 * Vscale) << c.label;
  }
}

TEST(RecursiveDynamics, PowerBalanceAlongForwardDynamics) {
  // With q̈ = FD(q, q̇, τ):  dE/dt = q̇ᵀ M q̈ + ½ q̇ᵀ Ṁ q̇ + gᵀ q̇ = q̇ᵀ τ.
  std::mt19937 rng(108);
  for (const Case& c : random_models(rng)) {
    const int n = c.model.nq;
    Data data(c.model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          tau = test::random_vector(rng, n, 20.0);
    const Eigen::VectorXd qdd = forward_dynamics(c.model, data, q, qd, tau);
    const Eigen::MatrixXd M = mass_matrix(c.model, data, q);
    const Eigen::VectorXd g = gravity_forces(c.model, data, q);
    const Eigen::MatrixXd Md = mdot_fd(c.model, q, qd, kH);
    const double Edot = qd.dot(M * qdd) + 0.5 * qd.dot(Md * qd) + g.dot(qd);
    const double scale = std::abs(qd.dot(M * qdd)) + std::abs(0.5 * qd.dot(Md * qd)) + std::abs(g.dot(qd)) +
                         std::abs(qd.dot(tau));
    EXPECT_NEAR(Edot, qd.dot(tau), kFdTol * scale) << c.label;
    // And dE/dt from the energies themselves along q(t) = q + q̇t + ½q̈t², q̇(t) = q̇ + q̈t.
    const double t = 1e-5;
    auto E = [&](double s) {
      const Eigen::VectorXd qs = q + s * qd + 0.5 * s * s * qdd, qds = qd + s * qdd;
      return kinetic_energy(c.model, data, qs, qds) + potential_energy(c.model, data, qs);
    };
    const double Edot_fd = (E(t) - E(-t)) / (2 * t);
    EXPECT_NEAR(Edot_fd, qd.dot(tau), kFdTol * scale + 1e-10 * std::abs(E(0)) / t) << c.label;
  }
}

// ---------------------------------------------------------------------------------------------
// Closed-form oracles

namespace {

struct Arm2R {
  double m1 = 1.7, m2 = 1.1, l1 = 0.8, l2 = 0.6, lc1 = 0.35, lc2 = 0.28, I1 = 0.09, I2 = 0.04, g = 9.81;

  Eigen::Matrix2d M(double q2) const {
    const double c2 = std::cos(q2);
    Eigen::Matrix2d M;
    M(0, 0) = m1 * lc1 * lc1 + I1 + m2 * (l1 * l1 + lc2 * lc2 + 2 * l1 * lc2 * c2) + I2;
    M(0, 1) = M(1, 0) = m2 * (lc2 * lc2 + l1 * lc2 * c2) + I2;
    M(1, 1) = m2 * lc2 * lc2 + I2;
    return M;
  }
  Eigen::Vector2d c(double q2, double qd1, double qd2) const {
    const double h = -m2 * l1 * lc2 * std::sin(q2);
    return {h * (2 * qd1 * qd2 + qd2 * qd2), -h * qd1 * qd1};
  }
  Eigen::Vector2d grav(double q1, double q2) const {
    const double c12 = std::cos(q1 + q2);
    return {(m1 * lc1 + m2 * l1) * g * std::cos(q1) + m2 * lc2 * g * c12, m2 * lc2 * g * c12};
  }
  double V(double q1, double q2) const {
    return m1 * g * lc1 * std::sin(q1) + m2 * g * (l1 * std::sin(q1) + lc2 * std::sin(q1 + q2));
  }
  /// A rod-like link along x: I_zz about the com = I, and I_yy = I, I_xx small.
  static Mat3 inertia(double I) { return Vec3(0.1 * I, I, I).asDiagonal(); }

  /// Built from LinkSpecs: joints about z at the link starts, gravity along −y.
  ModelDescription by_links() const {
    ModelDescription d;
    LinkSpec a;
    a.name = "upper";
    a.inertia = {m1, Vec3(lc1, 0, 0), inertia(I1)};
    d.add_link(a);
    LinkSpec b;
    b.name = "lower";
    b.parent = 0;
    b.placement = SE3::trans(Vec3(l1, 0, 0));
    b.inertia = {m2, Vec3(lc2, 0, 0), inertia(I2)};
    d.add_link(b);
    d.gravity = Vec3(0, -g, 0);
    d.add_point("tip", "lower", Vec3(l2, 0, 0));
    return d;
  }
  /// Built from a standard DH table with α = 0: DH frame i sits at the end of link i.
  ModelDescription by_dh() const {
    std::vector<DHRow> rows(2);
    rows[0].a = l1;
    rows[0].inertia = {m1, Vec3(lc1 - l1, 0, 0), inertia(I1)};
    rows[1].a = l2;
    rows[1].inertia = {m2, Vec3(lc2 - l2, 0, 0), inertia(I2)};
    ModelDescription d = from_dh(rows, DHConvention::Standard, "planar_2r");
    d.gravity = Vec3(0, -g, 0);
    d.add_point("tip", "link2", Vec3::Zero());
    return d;
  }
};

}  // namespace

TEST(ClosedForm, PlanarTwoLinkArm) {
  const Arm2R arm;
  std::mt19937 rng(201);
  for (const ModelDescription& d : {arm.by_links(), arm.by_dh()}) {
    const Model model = build_model(d);
    Data data(model);
    for (int rep = 0; rep < 20; ++rep) {
      const Eigen::VectorXd q = test::random_vector(rng, 2, 3.2), qd = test::random_vector(rng, 2, 3.0),
                            tau = test::random_vector(rng, 2, 10.0);
      const Eigen::Matrix2d M = arm.M(q[1]);
      const Eigen::Vector2d cc = arm.c(q[1], qd[0], qd[1]), gg = arm.grav(q[0], q[1]);
      EXPECT_TRUE(near(mass_matrix(model, data, q), M, 1e-14)) << d.name;
      EXPECT_TRUE(near(gravity_forces(model, data, q), gg, 1e-14, 1e-14)) << d.name;
      EXPECT_TRUE(near(bias_forces(model, data, q, qd), cc + gg, 1e-14, 1e-14)) << d.name;
      EXPECT_TRUE(near(trace_coriolis(model, data, q, qd), cc, 1e-13, 1e-13)) << d.name;
      EXPECT_TRUE(near(forward_dynamics(model, data, q, qd, tau), M.ldlt().solve(tau - cc - gg), 1e-13)) << d.name;
      EXPECT_NEAR(kinetic_energy(model, data, q, qd), 0.5 * qd.dot(M * qd), 1e-14 * qd.dot(M * qd));
      EXPECT_NEAR(potential_energy(model, data, q), arm.V(q[0], q[1]), 1e-13);
      forward_kinematics(model, data, q);
      const Vec3 tip(arm.l1 * std::cos(q[0]) + arm.l2 * std::cos(q[0] + q[1]),
                     arm.l1 * std::sin(q[0]) + arm.l2 * std::sin(q[0] + q[1]), 0);
      EXPECT_TRUE(near(point_position(model, data, 0), tip, 1e-15, 1e-15)) << d.name;
    }
  }
}

TEST(ClosedForm, SimplePendulum) {
  // Revolute about z, com at distance l below the pivot at θ = 0, gravity −y:
  // M = m l² + I,  c = 0,  g = m g l sin θ,  V = −m g l cos θ.
  const double m = 2.3, l = 0.7, I = 0.05, gr = 9.81;
  ModelDescription d;
  LinkSpec p;
  p.name = "bob";
  p.placement = SE3::trans(Vec3(0.2, 0.4, -0.1));  // pivot off the origin: V shifts by a constant
  p.inertia = {m, Vec3(0, -l, 0), Vec3(I, 0.5 * I, I).asDiagonal()};
  d.add_link(p);
  d.gravity = Vec3(0, -gr, 0);
  const Model model = build_model(d);
  Data data(model);
  for (double th : {-2.5, -1.0, 0.0, 0.3, 1.2, 3.0}) {
    Eigen::VectorXd q(1), qd(1), tau(1);
    q << th;
    qd << 1.7;
    tau << 0.4;
    EXPECT_NEAR(mass_matrix(model, data, q)(0, 0), m * l * l + I, 1e-14);
    EXPECT_NEAR(gravity_forces(model, data, q)[0], m * gr * l * std::sin(th), 1e-13);
    EXPECT_NEAR(bias_forces(model, data, q, qd)[0], m * gr * l * std::sin(th), 1e-13);
    EXPECT_NEAR(forward_dynamics(model, data, q, qd, tau)[0], (0.4 - m * gr * l * std::sin(th)) / (m * l * l + I),
                1e-13);
    // nq = 1 by both explicit algorithms.
    EXPECT_NEAR(forward_dynamics_crba(model, data, q, qd, tau)[0],
                (0.4 - m * gr * l * std::sin(th)) / (m * l * l + I), 1e-13);
    EXPECT_NEAR(forward_dynamics_aba(model, data, q, qd, tau)[0],
                (0.4 - m * gr * l * std::sin(th)) / (m * l * l + I), 1e-13);
    EXPECT_NEAR(potential_energy(model, data, q), m * gr * (0.4 - l * std::cos(th)), 1e-13);
    EXPECT_NEAR(kinetic_energy(model, data, q, qd), 0.5 * (m * l * l + I) * 1.7 * 1.7, 1e-13);
  }
}

TEST(ClosedForm, VerticalSlider) {
  // Prismatic along z against gravity −z: M = m, c = 0, g = m g, V = m g z.
  const double m = 4.2, gr = 9.81;
  ModelDescription d;
  LinkSpec s;
  s.name = "carriage";
  s.type = JointType::Prismatic;
  s.offset = 0.25;
  s.inertia = {m, Vec3(0.1, 0.2, 0.3), Vec3(0.1, 0.2, 0.25).asDiagonal()};
  d.add_link(s);
  const Model model = build_model(d);
  Data data(model);
  for (double z : {-1.0, 0.0, 0.5, 2.0}) {
    Eigen::VectorXd q(1), qd(1), tau(1);
    q << z;
    qd << -0.8;
    tau << 50.0;
    EXPECT_NEAR(mass_matrix(model, data, q)(0, 0), m, 1e-15);
    EXPECT_NEAR(gravity_forces(model, data, q)[0], m * gr, 1e-13);
    EXPECT_NEAR(bias_forces(model, data, q, qd)[0], m * gr, 1e-13);
    EXPECT_NEAR(forward_dynamics(model, data, q, qd, tau)[0], 50.0 / m - gr, 1e-13);
    EXPECT_NEAR(forward_dynamics_crba(model, data, q, qd, tau)[0], 50.0 / m - gr, 1e-13);
    EXPECT_NEAR(forward_dynamics_aba(model, data, q, qd, tau)[0], 50.0 / m - gr, 1e-13);
    EXPECT_NEAR(potential_energy(model, data, q), m * gr * (z + 0.25 + 0.3), 1e-12);
  }
}

TEST(ClosedForm, RadialSliderOnATurntable) {
  // Turntable (revolute z, inertia J) carrying a point-like slider of mass m along its x axis:
  // M = diag(J + m r² + I_s, m),  c = (2 m r ṙ θ̇, −m r θ̇²),  g = 0 (gravity along −z).
  const double J = 0.6, m = 1.4, Is = 0.02;
  ModelDescription d;
  LinkSpec t;
  t.name = "turntable";
  t.inertia = {3.0, Vec3::Zero(), Vec3(0.3, 0.3, J).asDiagonal()};
  d.add_link(t);
  LinkSpec s;
  s.name = "slider";
  s.parent = 0;
  s.type = JointType::Prismatic;
  s.axis = Vec3::UnitX();
  s.inertia = {m, Vec3::Zero(), Vec3(0.01, Is, Is).asDiagonal()};
  d.add_link(s);
  const Model model = build_model(d);
  Data data(model);
  std::mt19937 rng(202);
  for (int rep = 0; rep < 10; ++rep) {
    const Eigen::VectorXd q = test::random_vector(rng, 2, 2.0), qd = test::random_vector(rng, 2, 2.0);
    const double r = q[1];
    Eigen::Matrix2d M;
    M << J + m * r * r + Is, 0, 0, m;
    const Eigen::Vector2d cc(2 * m * r * qd[1] * qd[0], -m * r * qd[0] * qd[0]);
    EXPECT_TRUE(near(mass_matrix(model, data, q), M, 1e-14, 1e-14));
    EXPECT_TRUE(near(gravity_forces(model, data, q), Eigen::Vector2d::Zero(), 0, 1e-14));
    EXPECT_TRUE(near(bias_forces(model, data, q, qd), cc, 1e-14, 1e-14));
    EXPECT_TRUE(near(trace_coriolis(model, data, q, qd), cc, 1e-13, 1e-13));
  }
}
