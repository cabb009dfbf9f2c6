// Joint armature (rotor inertia reflected to the joint, I_r N²; LinkSpec::armature): M gains
// diag(a) in every route — the body-frame and world-frame CRBA, the fused M + bias sweep, the
// trace route, the generic core's CRBA and inverse dynamics (double and dual), the
// articulated-body algorithm (D_i = S_iᵀ IA_i S_i + a_i) — and τ = M q̈ + c + g, T = ½ q̇ᵀ M q̇
// with it. The oracle: a planar 2R arm's M by hand.
#include "refdyn/multibody/dual_dynamics.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

namespace refdyn {
namespace {

/// A planar 2R arm in the x-y plane (joints about z): uniform rods of mass m_k and length l_k,
/// centre of mass at l_k/2, I_zz about it m_k l_k²/12; armature a1, a2.
struct Planar2R {
  double m1 = 2.0, l1 = 0.5, m2 = 1.5, l2 = 0.4, a1 = 0.8, a2 = 0.3;
  ModelDescription description() const {
    ModelDescription d;
    auto rod = [](double m, double l) {
      LinkInertia in;
      in.mass = m;
      in.com = Vec3(l / 2, 0, 0);
      in.I_com = Vec3(1e-4, m * l * l / 12, m * l * l / 12).asDiagonal();
      return in;
    };
    LinkSpec s1;
    s1.name = "link1";
    s1.joint_name = "j1";
    s1.inertia = rod(m1, l1);
    s1.armature = a1;
    d.add_link(s1);
    LinkSpec s2;
    s2.name = "link2";
    s2.joint_name = "j2";
    s2.parent = 0;
    s2.placement = SE3::trans(Vec3(l1, 0, 0));
    s2.inertia = rod(m2, l2);
    s2.armature = a2;
    d.add_link(s2);
    d.gravity = Vec3(0, -9.81, 0);
    return d;
  }
  /// M by hand (Spong, Hutchinson, Vidyasagar §7.3.1, plus the armature on the diagonal).
  Eigen::Matrix2d by_hand(double q2) const {
    const double lc1 = l1 / 2, lc2 = l2 / 2, I1 = m1 * l1 * l1 / 12, I2 = m2 * l2 * l2 / 12, c2 = std::cos(q2);
    Eigen::Matrix2d M;
    M(0, 0) = I1 + m1 * lc1 * lc1 + I2 + m2 * (l1 * l1 + lc2 * lc2 + 2 * l1 * lc2 * c2) + a1;
    M(0, 1) = M(1, 0) = I2 + m2 * (lc2 * lc2 + l1 * lc2 * c2);
    M(1, 1) = I2 + m2 * lc2 * lc2 + a2;
    return M;
  }
};

Eigen::MatrixXd generic_crba(const Model& m, const Eigen::VectorXd& q) {
  const auto bodies = multibody::bodies_from_model<double>(m);
  const auto poses = multibody::forward_poses(bodies, std::vector<double>(q.data(), q.data() + q.size()));
  const std::vector<double> M = multibody::crba(bodies, poses);
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(M.data(), m.nq, m.nq);
}

Eigen::MatrixXd generic_mass_matrix(const Model& m, const Eigen::VectorXd& q) {
  const auto bodies = multibody::bodies_from_model<double>(m);
  const auto poses = multibody::forward_poses(bodies, std::vector<double>(q.data(), q.data() + q.size()));
  const std::vector<double> M = multibody::mass_matrix(bodies, poses);
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(M.data(), m.nq, m.nq);
}

TEST(Armature, Planar2RMassMatrixEqualsTheHandComputationInEveryRoute) {
  const Planar2R arm;
  const Model model = build_model(arm.description());
  Data data(model);
  const Eigen::Vector2d q(0.3, 0.7), qd(0.4, -1.1);
  const Eigen::Matrix2d hand = arm.by_hand(q[1]);
  const Eigen::MatrixXd M = mass_matrix(model, data, q);
  std::printf("planar 2R, q = (0.3, 0.7), a = (0.8, 0.3): M = [%.15g %.15g; %.15g %.15g], by hand [%.15g %.15g; %.15g %.15g]\n",
              M(0, 0), M(0, 1), M(1, 0), M(1, 1), hand(0, 0), hand(0, 1), hand(1, 0), hand(1, 1));
  EXPECT_TRUE(test::near(M, hand, 1e-14, 1e-15)) << "body-frame CRBA";
  EXPECT_TRUE(test::near(trace_mass_matrix(model, data, q), hand, 1e-14, 1e-15)) << "trace route";
  EXPECT_TRUE(test::near(generic_crba(model, q), hand, 1e-14, 1e-15)) << "generic CRBA";
  EXPECT_TRUE(test::near(generic_mass_matrix(model, q), hand, 1e-14, 1e-15)) << "generic inverse-dynamics columns";
  unchecked::mass_matrix_and_bias(model, data, q, qd);
  EXPECT_TRUE(test::near(data.M, hand, 1e-14, 1e-15)) << "fused M + bias";
  // Without armature the same model's M is the hand computation minus diag(a).
  ModelDescription bare = arm.description();
  for (LinkSpec& l : bare.links) l.armature = 0;
  const Model bare_model = build_model(bare);
  Data bare_data(bare_model);
  Eigen::Matrix2d hand_bare = hand;
  hand_bare(0, 0) -= arm.a1;
  hand_bare(1, 1) -= arm.a2;
  EXPECT_TRUE(test::near(mass_matrix(bare_model, bare_data, q), hand_bare, 1e-14, 1e-15));
}

/// Random chains and trees (revolute and prismatic joints, fixed links folded) with an armature
/// on about two joints in three.
struct ArmatureCase {
  std::string label;
  ModelDescription with, without;
};
std::vector<ArmatureCase> armature_cases(std::mt19937& rng) {
  std::vector<ArmatureCase> out;
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int n : {1, 2, 3, 4, 6, 7, 9, 12}) {
    for (int variant = 0; variant < 2; ++variant) {
      test::RandomChainOptions o;
      o.dof = n;
      o.tree = variant == 1;
      o.with_fixed_joints = variant == 1;
      ArmatureCase c;
      c.label = (o.tree ? "tree n=" : "chain n=") + std::to_string(n);
      c.without = test::random_chain(rng, o);
      c.with = c.without;
      for (LinkSpec& l : c.with.links)
        if (l.type != JointType::Fixed && U(rng) < 0.67) l.armature = 0.05 + 2.0 * U(rng);
      out.push_back(std::move(c));
    }
  }
  return out;
}

TEST(Armature, EveryMassMatrixRouteAddsTheDiagonal) {
  std::mt19937 rng(33);
  for (const ArmatureCase& c : armature_cases(rng)) {
    SCOPED_TRACE(c.label);
    const Model with = build_model(c.with), without = build_model(c.without);
    Data dw(with), d0(without);
    const Eigen::VectorXd q = test::random_vector(rng, with.nq), qd = test::random_vector(rng, with.nq);
    const Eigen::MatrixXd a = Eigen::Map<const Eigen::VectorXd>(with.armature.data(), with.nq).asDiagonal();
    const Eigen::MatrixXd M0 = mass_matrix(without, d0, q);
    const Eigen::MatrixXd expected = M0 + a;
    EXPECT_TRUE(test::near(mass_matrix(with, dw, q), expected, 1e-13, 1e-14)) << "CRBA";
    EXPECT_TRUE(test::near(trace_mass_matrix(with, dw, q), expected, 1e-10, 1e-12)) << "trace route";
    EXPECT_TRUE(test::near(generic_crba(with, q), expected, 1e-12, 1e-13)) << "generic CRBA";
    EXPECT_TRUE(test::near(generic_mass_matrix(with, q), expected, 1e-12, 1e-13)) << "generic ID columns";
    unchecked::mass_matrix_and_bias(with, dw, q, qd);
    EXPECT_TRUE(test::near(dw.M, expected, 1e-13, 1e-14)) << "fused M + bias";
    // The joints without armature keep their diagonal entries bit for bit.
    const Eigen::MatrixXd Mw = mass_matrix(with, dw, q);
    for (int i = 0; i < with.nq; ++i)
      if (with.armature[i] == 0) {
        EXPECT_EQ(Mw(i, i), M0(i, i)) << "joint " << i;
      }
  }
}

TEST(Armature, ArticulatedBodyEqualsCrbaAndCholesky) {
  std::mt19937 rng(34);
  double worst = 0;
  for (const ArmatureCase& c : armature_cases(rng)) {
    SCOPED_TRACE(c.label);
    const Model m = build_model(c.with);
    Data da(m), dc(m);
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::VectorXd q = test::random_vector(rng, m.nq), qd = test::random_vector(rng, m.nq),
                            tau = test::random_vector(rng, m.nq, 5.0);
      const Eigen::VectorXd aba = forward_dynamics_aba(m, da, q, qd, tau);
      const Eigen::VectorXd crba = forward_dynamics_crba(m, dc, q, qd, tau);
      EXPECT_TRUE(test::near(aba, crba, 1e-10, 1e-11));
      worst = std::max(worst, test::rel_diff(aba, crba));
      // the articulated-body factorization solves M x = b, armature included
      Eigen::VectorXd x = tau;
      unchecked::aba_solve(m, da, tau.data(), x.data());
      EXPECT_TRUE(test::near(mass_matrix(m, dc, q) * x, tau, 1e-10, 1e-11));
    }
  }
  std::printf("ABA vs CRBA + Cholesky with armature: worst relative difference %.1e\n", worst);
}

TEST(Armature, InverseDynamicsAndKineticEnergyCarryIt) {
  std::mt19937 rng(35);
  for (const ArmatureCase& c : armature_cases(rng)) {
    SCOPED_TRACE(c.label);
    const Model m = build_model(c.with);
    Data data(m);
    const Eigen::VectorXd q = test::random_vector(rng, m.nq), qd = test::random_vector(rng, m.nq),
                          qdd = test::random_vector(rng, m.nq);
    const Eigen::MatrixXd M = mass_matrix(m, data, q);
    const Eigen::VectorXd nle = bias_forces(m, data, q, qd);
    const Eigen::VectorXd tau = inverse_dynamics(m, data, q, qd, qdd);
    EXPECT_TRUE(test::near(tau, M * qdd + nle, 1e-12, 1e-12)) << "RNEA";
    // generic core over dual numbers (the jerk planner's and the Jacobians' route)
    std::vector<JacobianScalar> Q(m.nq), QD(m.nq), QDD(m.nq), T(m.nq);
    for (int i = 0; i < m.nq; ++i) Q[i] = q[i], QD[i] = qd[i], QDD[i] = qdd[i];
    inverse_dynamics_dual(m, Q.data(), QD.data(), QDD.data(), true, T.data());
    Eigen::VectorXd td(m.nq);
    for (int i = 0; i < m.nq; ++i) td[i] = T[i].v;
    EXPECT_TRUE(test::near(td, tau, 1e-12, 1e-12)) << "inverse_dynamics_dual";
    const double T_expected = 0.5 * qd.dot(M * qd);
    EXPECT_NEAR(kinetic_energy(m, data, q, qd), T_expected, 1e-12 * (1 + T_expected));
    EXPECT_NEAR(trace_kinetic_energy(m, data, q, qd), T_expected, 1e-10 * (1 + T_expected));
  }
}

TEST(Armature, RefusedWhereItMeansNothing) {
  ModelDescription d = Planar2R().description();
  d.links[1].armature = -0.1;
  test::expect_error_mentioning([&] { build_model(d); }, {"link2", "armature", ">= 0"});
  d.links[1].armature = std::nan("");
  test::expect_error_mentioning([&] { build_model(d); }, {"armature", "finite"});
  d.links[1].armature = 0.1;
  d.links[1].type = JointType::Fixed;
  test::expect_error_mentioning([&] { build_model(d); }, {"fixed joint has no armature"});
}

}  // namespace
}  // namespace refdyn
