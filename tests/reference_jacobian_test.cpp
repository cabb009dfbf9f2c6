// ReferenceDynamics::jacobian (the exact ∂f/∂x of implicit integration) against central finite
// differences of derivative(), which are allowed here in the tests and nowhere in the engine.
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/simulate/plan.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <random>

namespace refdyn {
namespace {

/// Central differences of f along each state coordinate, step scaled to the coordinate.
Eigen::MatrixXd central_differences(ReferenceDynamics& rd, double t, const Eigen::VectorXd& x) {
  const int nx = static_cast<int>(x.size());
  Eigen::MatrixXd J(nx, nx);
  Eigen::VectorXd xp = x, fp(nx), fm(nx);
  for (int j = 0; j < nx; ++j) {
    const double h = 1e-6 * std::max(1.0, std::abs(x[j]));
    xp[j] = x[j] + h;
    rd.derivative(t, xp, fp);
    xp[j] = x[j] - h;
    rd.derivative(t, xp, fm);
    xp[j] = x[j];
    J.col(j) = (fp - fm) / (2 * h);
  }
  return J;
}

/// ‖J − J_fd‖ entrywise within rel·max|J| + abs: FD carries ~1e-9 relative truncation and
/// rounding error with these steps, so 1e-7 of the largest entry separates a right Jacobian from
/// a wrong one by orders of magnitude.
void expect_jacobian_matches(ReferenceDynamics& rd, double t, const Eigen::VectorXd& x, double rel = 1e-7) {
  Eigen::MatrixXd J;
  rd.jacobian(t, x, J);
  const Eigen::MatrixXd Jfd = central_differences(rd, t, x);
  ASSERT_EQ(J.rows(), x.size());
  ASSERT_EQ(J.cols(), x.size());
  const double scale = std::max(1.0, Jfd.cwiseAbs().maxCoeff());
  EXPECT_LE((J - Jfd).cwiseAbs().maxCoeff(), rel * scale) << "J =\n" << J << "\nFD =\n" << Jfd;
}

TEST(ReferenceJacobian, UnconstrainedArmWithEveryForceElementMatchesFiniteDifferences) {
  std::mt19937 rng(21);
  test::RandomChainOptions opt;
  opt.dof = 5;
  const Model model = build_model(test::random_chain(rng, opt));
  ForceSet forces;
  forces.add(joint_damping(model, model.joint_name[0], 0.7));
  forces.add(joint_spring(model, model.joint_name[1], 30.0, 0.2));
  forces.add(joint_effort(model, model.joint_name[2], constant(1.5)));
  forces.add(std::make_shared<FlexibleDrive>(model, model.joint_name[3], FlexibleDriveParams{200.0, 3.0}, constant(0.4)));
  forces.add(std::make_shared<LuGreFriction>(model, model.joint_name[4], LuGreParams{0.1, 0.2, 1e3, 30.0, 0.1, 0.175}));
  forces.add(std::make_shared<LuGreFriction>(model, model.joint_name[1], LuGreParams{0.3, 0.2, 50.0, 2.0, 0.0, 0.1}));
  const ConstraintSet none;
  ReferenceDynamics rd(model, forces, none);
  for (int trial = 0; trial < 4; ++trial) {
    Eigen::VectorXd x = test::random_vector(rng, rd.state_size());
    x.tail(2) *= 1e-3;  // bristle deflections are small
    expect_jacobian_matches(rd, 0.3 * trial, x);
  }
}

TEST(ReferenceJacobian, PaperArmWithStiffFrictionMatchesFiniteDifferences) {
  models::PaperExampleParams p;
  p.lugre_rot.sigma0 = 1e5;
  p.lugre_rot.sigma1 = 300;
  models::PaperExample ex(p);
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  std::mt19937 rng(5);
  Eigen::VectorXd x = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3));
  for (int trial = 0; trial < 3; ++trial) {
    Eigen::VectorXd xt = x;
    xt.segment(3, 3) = test::random_vector(rng, 3, 0.5);
    xt.tail(3) = test::random_vector(rng, 3, 1e-6);
    expect_jacobian_matches(rd, 1.0 + trial, xt);
  }
}

// The example mechanisms: a closed loop with a rheonomic drive row (four-bar), first-order rows
// (knife-edge unicycle), an acceleration-level row (waiter tray), and a 7-DOF arm with an
// expression row, each with the Lagrange and the projection solver where both apply.
TEST(ReferenceJacobian, ExampleMechanismsMatchFiniteDifferences) {
  std::mt19937 rng(8);
  for (const char* rel : {"examples/four_bar/four_bar.yaml", "examples/unicycle/unicycle.yaml",
                          "examples/waiter_tray/waiter_tray.yaml", "examples/urdf_arm_line/urdf_arm_line.yaml",
                          "examples/planar_2r_circle/planar_2r_circle.yaml"}) {
    SCOPED_TRACE(rel);
    auto s = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/" + rel);
    for (const ReferenceSolver solver : {ReferenceSolver::Lagrange, ReferenceSolver::Projection}) {
      ReferenceDynamicsOptions o = s->options;
      o.solver = solver;
      ReferenceDynamics rd(s->model, s->forces, s->constraints, o);
      Eigen::VectorXd x = rd.make_state(s->q0, s->qd0);
      x.segment(rd.nq(), rd.nq()) += test::random_vector(rng, rd.nq(), 0.1);  // off the constraints: Baumgarte terms act
      expect_jacobian_matches(rd, s->integrator.t0 + 0.37, x);
    }
  }
}

TEST(ReferenceJacobian, RefusesWhatItCannotDifferentiate) {
  models::PaperExample ex;
  ReferenceDynamicsOptions o = ex.options();
  o.paper_literal_forces = true;
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, o);
  Eigen::MatrixXd J;
  test::expect_error_mentioning([&] { rd.jacobian(0.0, rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), J); },
                          {"paper_literal_forces"});
  // A user's force element without a dual evaluation is named.
  struct Push final : ForceElement {
    std::string name() const override { return "push"; }
    void apply(double, const Eigen::VectorXd&, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
               Eigen::MatrixXd*) const override {
      Q[0] += 1.0;
    }
  };
  ForceSet forces = ex.forces;
  forces.add(std::make_shared<Push>());
  ReferenceDynamics rd2(ex.model, forces, ex.constraints, ex.options());
  test::expect_error_mentioning([&] { rd2.jacobian(0.0, rd2.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), J); },
                                {"force element 'push' has no exact derivatives", "method: rk4 or dopri5"});
}

}  // namespace
}  // namespace refdyn
