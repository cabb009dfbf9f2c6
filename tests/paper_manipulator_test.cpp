// The paper's three-link manipulator (column ψ1, rotary arm ψ2, sliding link z3).
#include "refdyn/models/paper_manipulator.hpp"

#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <numbers>

using namespace refdyn;
using refdyn::test::near;

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

Eigen::VectorXd vec3(double a, double b, double c) {
  Eigen::VectorXd v(3);
  v << a, b, c;
  return v;
}
}  // namespace

TEST(PaperManipulator, Structure) {
  const Model model = models::paper_manipulator();
  ASSERT_EQ(model.nq, 3);
  EXPECT_EQ(model.joint_type[0], JointType::Revolute);
  EXPECT_EQ(model.joint_type[1], JointType::Revolute);
  EXPECT_EQ(model.joint_type[2], JointType::Prismatic);
  EXPECT_EQ(model.parent[0], -1);
  EXPECT_EQ(model.parent[1], 0);
  EXPECT_EQ(model.parent[2], 1);
  EXPECT_EQ(model.body_index("column"), 0);
  EXPECT_EQ(model.body_index("arm"), 1);
  EXPECT_EQ(model.body_index("slider"), 2);
  EXPECT_EQ(model.joint_index("z3"), 2);
  EXPECT_NO_THROW(model.point_index("E"));
  EXPECT_NEAR(model.total_mass(), 31.0, 1e-12);
}

TEST(PaperManipulator, MassMatrixSymmetricPositiveDefiniteOnAGrid) {
  const Model model = models::paper_manipulator();
  Data data(model);
  double min_eig = std::numeric_limits<double>::infinity();
  for (double psi1 : {0.0, 0.7, -2.0, kPi}) {
    for (int k = 0; k < 36; ++k) {  // ψ2 over a full turn in 10° steps
      const double psi2 = k * 10 * kDeg;
      for (int j = 0; j <= 9; ++j) {  // z3 in [0.1, 1.0]
        const double z3 = 0.1 + 0.1 * j;
        const Eigen::VectorXd q = vec3(psi1, psi2, z3);
        const Eigen::MatrixXd M = mass_matrix(model, data, q);
        ASSERT_TRUE(near(M, M.transpose(), 0, 0));
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
        EXPECT_GT(es.eigenvalues().minCoeff(), 0.0) << "q = " << q.transpose();
        min_eig = std::min(min_eig, es.eigenvalues().minCoeff());
        EXPECT_TRUE(near(trace_mass_matrix(model, data, q), M, 1e-13)) << "q = " << q.transpose();
        // The slider's own mass is the (z3, z3) entry; ψ1 does not enter M.
        EXPECT_NEAR(M(2, 2), 3.0, 1e-13);
        EXPECT_TRUE(near(mass_matrix(model, data, vec3(0.0, psi2, z3)), M, 1e-13));
      }
    }
  }
  RecordProperty("min_eigenvalue_on_grid", std::to_string(min_eig));
}

TEST(PaperManipulator, EndEffectorPosition) {
  const Model model = models::paper_manipulator();
  Data data(model);
  const int E = model.point_index("E");
  // The spec's configuration: q = [0, 225°, 0.5] → E = (0.5 cos45°, 0, 0.6 + 0.5 sin45°).
  forward_kinematics(model, data, vec3(0, 225 * kDeg, 0.5));
  const double s = std::sqrt(0.5);
  EXPECT_TRUE(near(point_position(model, data, E), Vec3(0.5 * s, 0, 0.6 + 0.5 * s), 1e-15, 1e-15));
  // In general, with ψ2 = 270° − ε the sliding link points along (cos ε cos ψ1, cos ε sin ψ1, sin ε)
  // from joint 2 at height 0.6, and E is z3 along it.
  for (double psi1 : {-2.0, 0.0, 0.4, 1.5, 3.0})
    for (double eps : {-1.2, -0.3, 0.0, 0.45, 1.0, 2.5})
      for (double z3 : {0.1, 0.55, 1.0}) {
        forward_kinematics(model, data, vec3(psi1, 270 * kDeg - eps, z3));
        const Vec3 dir(std::cos(eps) * std::cos(psi1), std::cos(eps) * std::sin(psi1), std::sin(eps));
        EXPECT_TRUE(near(point_position(model, data, E), Vec3(0, 0, models::kPaperH1) + z3 * dir, 1e-15, 1e-15))
            << "psi1 " << psi1 << " eps " << eps << " z3 " << z3;
        // The sliding joint moves E along the same direction: column 3 of C is `dir`.
        point_jacobian(model, data, E);
        EXPECT_TRUE(near(data.Jp.col(2), dir, 1e-15, 1e-15));
      }
}

TEST(PaperManipulator, FreeMotionConservesEnergyUnderRK4) {
  // No constraints, no friction, τ = 0: E = T + V is a first integral. Classical RK4, h = 1e-3,
  // 5 s from q0 = [0, 225°, 0.5], q̇0 = [1, 0.5, 0.2].
  const Model model = models::paper_manipulator();
  Data data(model);
  const int n = model.nq;
  const Eigen::VectorXd tau = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd q = vec3(0, 225 * kDeg, 0.5), qd = vec3(1.0, 0.5, 0.2);
  auto energy = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    return kinetic_energy(model, data, a, b) + potential_energy(model, data, a);
  };
  auto acc = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) -> Eigen::VectorXd {
    return forward_dynamics(model, data, a, b, tau);
  };
  const double h = 1e-3, E0 = energy(q, qd);
  const int steps = 5000;
  double worst = 0, z_min = q[2], z_max = q[2];
  for (int s = 0; s < steps; ++s) {
    const Eigen::VectorXd k1q = qd, k1v = acc(q, qd);
    const Eigen::VectorXd k2q = qd + 0.5 * h * k1v, k2v = acc(q + 0.5 * h * k1q, k2q);
    const Eigen::VectorXd k3q = qd + 0.5 * h * k2v, k3v = acc(q + 0.5 * h * k2q, k3q);
    const Eigen::VectorXd k4q = qd + h * k3v, k4v = acc(q + h * k3q, k4q);
    q += h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q);
    qd += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    ASSERT_TRUE(q.allFinite() && qd.allFinite()) << "step " << s;
    worst = std::max(worst, std::abs(energy(q, qd) - E0) / std::abs(E0));
    z_min = std::min(z_min, q[2]);
    z_max = std::max(z_max, q[2]);
  }
  std::printf("paper manipulator RK4 h=1e-3, 5 s: E0 = %.12g J, worst |E - E0|/|E0| = %.3e, z3 in [%.3f, %.3f]\n",
              E0, worst, z_min, z_max);
  RecordProperty("worst_relative_energy_drift", std::to_string(worst));
  EXPECT_LE(worst, 1e-8);
  // The motion is not trivial: the energy moved between T and V.
  EXPECT_GT(std::abs(kinetic_energy(model, data, q, qd) - kinetic_energy(model, data, vec3(0, 225 * kDeg, 0.5),
                                                                        vec3(1.0, 0.5, 0.2))),
            1e-2 * std::abs(E0));
}
