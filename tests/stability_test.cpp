// rk4_step_stability (simulate/stability.hpp) against RK4's stability function, and the reports of
// failed plans (docs/implicit.md, "When a run fails"): a stiff problem under RK4 is called stiff
// (not by its symptom), a singular constraint Jacobian is told from an ill-conditioned partition.
#include "refdyn/models/paper_example.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/stability.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <complex>

namespace refdyn {
namespace {

// On the negative real axis RK4 is stable for hλ ≥ −2.7852935634…
TEST(Stability, RealEigenvalueBoundary) {
  Eigen::MatrixXd J(1, 1);
  J(0, 0) = -1000.0;
  const double h_max = 2.7852935634 / 1000.0;
  EXPECT_TRUE(rk4_step_stability(J, 0.99 * h_max).stable);
  const StepStability s = rk4_step_stability(J, 1e-2);
  EXPECT_FALSE(s.stable);
  EXPECT_NEAR(s.largest_stable_step, h_max, 1e-9);
  EXPECT_DOUBLE_EQ(s.spectral_radius, 1000.0);
  EXPECT_EQ(s.worst, std::complex<double>(-1000.0, 0.0));
}

// A damped oscillator x'' + 2ζω x' + ω² x = 0: the step bound of its complex pair, checked
// against |R(hλ)| directly.
TEST(Stability, ComplexPairAgainstTheStabilityFunction) {
  const double w = 300, zeta = 0.1;
  Eigen::MatrixXd J(2, 2);
  J << 0, 1, -w * w, -2 * zeta * w;
  const StepStability s = rk4_step_stability(J, 0.1);
  ASSERT_FALSE(s.stable);
  const std::complex<double> lambda(-zeta * w, w * std::sqrt(1 - zeta * zeta));
  auto R = [](std::complex<double> z) { return std::abs(1.0 + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0); };
  EXPECT_LE(R(s.largest_stable_step * lambda), 1.0 + 1e-6);
  EXPECT_GT(R(1.01 * s.largest_stable_step * lambda), 1.0);
  EXPECT_NEAR(std::abs(s.worst), w, 1e-9 * w);
  test::expect_error_mentioning([] { rk4_step_stability(Eigen::MatrixXd::Zero(2, 3), 0.1); }, {"square"});
}

// A mode that grows physically (an inverted pendulum falling, λ = +3) is not a numerical
// instability: RK4 follows e^{hλ} (it grows a little less), at any step that resolves it.
TEST(Stability, PhysicalGrowthIsNotAnInstability) {
  Eigen::MatrixXd J(2, 2);
  J << 0, 1, 9, 0;  // θ'' = 9 θ: λ = ±3
  EXPECT_TRUE(rk4_step_stability(J, 1e-3).stable);
  EXPECT_TRUE(rk4_step_stability(J, 0.2).stable);
  EXPECT_FALSE(rk4_step_stability(J, 1.0).stable);  // the λ = −3 mode: h·λ = −3 < −2.785
}

// The paper's plan with stiff friction (σ0 = 1e5, σ1 = 300) under RK4 at 1e-3 s: it fails, and the
// report says the step is unstable because the problem is stiff — not the partition it broke.
TEST(Stability, StiffPaperPlanUnderRk4IsReportedAsStiff) {
  models::PaperExampleParams p;
  p.lugre_rot.sigma0 = p.lugre_lin.sigma0 = 1e5;
  p.lugre_rot.sigma1 = p.lugre_lin.sigma1 = 300;
  p.t1 = 0.5;
  models::PaperExample ex(p);
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  const Plan plan = plan_motion(rd, rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), {ex.integrator()});
  ASSERT_FALSE(plan.summary.ok());
  const std::string& m = plan.summary.message;
  EXPECT_EQ(m.rfind("the integration is unstable at step h = 0.001 s: the problem is stiff", 0), 0u) << m;
  EXPECT_NE(m.find("use method: bdf"), std::string::npos) << m;
  EXPECT_NE(m.find("The run ended with: "), std::string::npos) << m;
  // The soft paper study is not called stiff: it succeeds.
  models::PaperExampleParams soft;
  soft.t1 = 0.5;
  models::PaperExample ex_soft(soft);
  ReferenceDynamics rd_soft(ex_soft.model, ex_soft.forces, ex_soft.constraints, ex_soft.options());
  EXPECT_TRUE(plan_motion(rd_soft, rd_soft.make_state(ex_soft.q0(), Eigen::VectorXd::Zero(3)), {ex_soft.integrator()}).summary.ok());
}

// Two rows that say the same thing: A is singular (rank 1 of 2), which no partition can fix.
TEST(Stability, SingularConstraintJacobianIsToldFromABadPartition) {
  models::PaperExample ex;
  ConstraintSet rows;
  for (const auto& c : ex.constraints.constraints()) rows.add(c);
  NewConstraint twice = point_coordinate(ex.model, "E", 2, ex.z_a);
  twice->name = "height_again";
  rows.add(twice);
  ReferenceDynamicsOptions o = ex.options();
  o.independent.clear();
  ReferenceDynamics rd(ex.model, ex.forces, rows, o);
  IntegratorOptions io = ex.integrator();
  io.t1 = 0.01;
  const Plan plan = plan_motion(rd, rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), {io});
  ASSERT_EQ(plan.summary.status, IntegrationStatus::NumericalFailure) << plan.summary.message;
  const std::string& m = plan.summary.message;
  EXPECT_NE(m.find("the constraint Jacobian A is singular"), std::string::npos) << m;
  EXPECT_NE(m.find("smallest singular value"), std::string::npos) << m;
  EXPECT_NE(m.find("psi1 = "), std::string::npos) << m;  // the configuration
}

}  // namespace
}  // namespace refdyn
