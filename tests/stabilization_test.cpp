// Drift-free stabilization (stabilization: projection | both): long runs of the example
// mechanisms stay on their constraints without Baumgarte gains, the projection is the least
// change in the mass metric, and its bad input and failures are reported.
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/plan.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>

namespace refdyn {
namespace {

std::string example(const std::string& rel) { return test::read_file(std::string(REFDYN_SOURCE_DIR) + "/" + rel); }

/// The text with `from` replaced by `to` (once; the test fails if `from` is absent).
std::string edited(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "the example no longer contains: " << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

struct Outcome {
  std::unique_ptr<Problem> problem;
  std::unique_ptr<ReferenceDynamics> rd;
  Plan plan;
  double worst_phi = 0, worst_phid = 0;  // over every sample: |Φ| or |c|, and |Φ̇| of holonomic rows
};

Outcome plan_text(const std::string& yaml, const std::string& name) {
  Outcome r;
  r.problem = io::parse_problem(yaml, name);
  Problem& s = *r.problem;
  r.rd = std::make_unique<ReferenceDynamics>(s.model, s.forces, s.constraints, s.options);
  r.plan = plan_motion(*r.rd, r.rd->make_state(s.q0, s.qd0), {s.integrator, s.residual_from});
  for (size_t k = 0; k < r.plan.phi.size(); ++k) {
    r.worst_phi = std::max(r.worst_phi, r.plan.phi[k].cwiseAbs().maxCoeff());
    for (int row = 0; row < s.constraints.rows(); ++row)
      if (s.constraints.row_order(row) == 0) r.worst_phid = std::max(r.worst_phid, std::abs(r.plan.phid[k][row]));
  }
  return r;
}

// 100 s of the four-bar (100,000 RK4 steps, the crank turning 100 times): with the projection and
// no Baumgarte gain the loop stays closed to 1e-10 in position and velocity.
TEST(Stabilization, FourBarStaysClosedForAHundredSecondsWithoutBaumgarte) {
  const std::string base = edited(example("examples/four_bar/four_bar.yaml"), "t0: 0, t1: 2}", "t0: 0, t1: 100, output_interval: 0.1}");
  const Outcome p = plan_text(base + "\nstabilization: projection\n", "four_bar_projection");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  EXPECT_EQ(p.rd->options().alpha, 0.0);
  EXPECT_EQ(p.rd->options().beta, 0.0);
  EXPECT_LT(p.worst_phi, 1e-10);
  EXPECT_LT(p.worst_phid, 1e-10);
  EXPECT_GT(p.plan.summary.projections, 0);
  EXPECT_GT(p.plan.summary.max_projection_correction, 0.0);
  EXPECT_LT(p.plan.summary.max_projection_correction, 1e-6);  // corrections of the drift of one step
  // The same equations without the projection (and without Baumgarte) drift: the projection is
  // what keeps the loop closed.
  const Outcome free = plan_text(base + "\nbaumgarte: {alpha: 0, beta: 0}\n", "four_bar_free");
  std::printf("[ four-bar, 100 s, RK4 1e-3 ] max |Phi|: projection %.3g, no stabilization %.3g; corrections %ld, "
              "largest %.3g\n", p.worst_phi, free.worst_phi, p.plan.summary.projections,
              p.plan.summary.max_projection_correction);
  EXPECT_GT(free.worst_phi, 100 * p.worst_phi);
}

// 100 s of the knife-edge unicycle (first-order rows only): |c| stays below 1e-10.
TEST(Stabilization, KnifeEdgeKeepsItsVelocityConstraintsForAHundredSeconds) {
  std::string yaml = edited(example("examples/unicycle/unicycle.yaml"), "baumgarte: {beta_first_order: 50}", "stabilization: projection");
  yaml = edited(yaml, "t0: 0, t1: 8}", "t0: 0, t1: 100, output_interval: 0.1}");
  const Outcome p = plan_text(yaml, "unicycle_projection");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  EXPECT_EQ(p.rd->options().beta_first_order, 0.0);
  EXPECT_LT(p.worst_phi, 1e-10);
  // Still the physics: P on the circle of radius v0/omega about (0, v0/omega).
  const Problem& s = *p.problem;
  const double R = s.parameters.at("v0") / s.parameters.at("omega");
  const Eigen::VectorXd& x = p.plan.x.back();
  EXPECT_NEAR(std::hypot(x[0], x[1] - R), R, 1e-6);
}

// BDF with the projection (CVODE's projection step): the same bound on the four-bar.
TEST(Stabilization, ProjectionWithBdf) {
  std::string yaml = edited(example("examples/four_bar/four_bar.yaml"), "{method: rk4, step: 1e-3, t0: 0, t1: 2}",
                            "{method: bdf, rtol: 1e-8, atol: 1e-10, step: 0.01, t0: 0, t1: 20}");
  const Outcome p = plan_text(yaml + "\nstabilization: projection\n", "four_bar_bdf_projection");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  EXPECT_LT(p.worst_phi, 1e-10);
  EXPECT_LT(p.worst_phid, 1e-10);
  EXPECT_GT(p.plan.summary.jacobian_evaluations, 0);
}

// The projection is the least change in the metric of M: the correction δq is M⁻¹Aᵀ μ for some μ
// (orthogonal, in M, to the constraint's tangent space), and the result satisfies Φ = 0, Φ̇ = 0.
TEST(Stabilization, ProjectionIsTheMassWeightedLeastChange) {
  auto s = io::parse_problem(example("examples/four_bar/four_bar.yaml") + "\nstabilization: both\n", "four_bar_both");
  ReferenceDynamics rd(s->model, s->forces, s->constraints, s->options);
  std::mt19937 rng(3);
  Eigen::VectorXd x = rd.make_state(s->q0, s->qd0);
  const double t = 0.3;
  rd.project_state(t, x);  // on the constraints (velocities consistent at t)
  Eigen::VectorXd y = x;
  y.head(3) += test::random_vector(rng, 3, 1e-4);
  y.segment(3, 3) += test::random_vector(rng, 3, 1e-3);
  const Eigen::VectorXd before = y;
  const ReferenceDynamics::StateProjection p = rd.project_state(t, y);
  EXPECT_LT(p.residual_after, 1e-12);
  EXPECT_GT(p.residual_before, 1e-6);
  EXPECT_GT(p.iterations, 1);
  // Stationarity of ½ δqᵀ M δq on Φ = 0 at the result: M δq lies in the row space of A (up to the
  // Newton iterates' curvature, small for a 1e-4 perturbation).
  ConstraintEval ev(s->model, s->constraints);
  Data data(s->model);
  const Eigen::VectorXd q = y.head(3);
  evaluate_constraints(s->model, data, s->constraints, ev, t, q, y.segment(3, 3));
  unchecked::crba(s->model, data, q);
  const Eigen::VectorXd Mdqd = data.M * (y.segment(3, 3) - before.segment(3, 3));
  // velocity level: exactly one linear step, so M δq̇ ∈ range(Aᵀ) to rounding
  const Eigen::MatrixXd At = ev.A.transpose();
  const Eigen::VectorXd fit = At * At.colPivHouseholderQr().solve(Mdqd);
  EXPECT_LT((fit - Mdqd).norm(), 1e-9 * Mdqd.norm() + 1e-14);
}

TEST(Stabilization, BadInputIsALocatedError) {
  const std::string four_bar = example("examples/four_bar/four_bar.yaml");
  test::expect_error_mentioning([&] { io::parse_problem(four_bar + "\nstabilization: projected\n", "x"); },
                          {"stabilization", "projection"});
  test::expect_error_mentioning([&] { io::parse_problem(four_bar + "\nstabilization: projection\nbaumgarte: {alpha: 10}\n", "x"); },
                          {"baumgarte", "stabilization: both"});
  test::expect_error_mentioning([&] { io::parse_problem(four_bar + "\nstabilization: {method: both, tolerance: 0}\n", "x"); },
                          {"projection_tolerance"});
  test::expect_error_mentioning([&] { io::parse_problem(four_bar + "\nstabilization: {method: both, max_iterations: 0.5}\n", "x"); },
                          {"stabilization.max_iterations"});
  test::expect_error_mentioning([&] { io::parse_problem(four_bar + "\nstabilization: {tolerance: 1e-9}\n", "x"); },
                          {"method"});
  // No constraint to project onto.
  std::string unconstrained = four_bar.substr(0, four_bar.find("constraints:")) +
                              "initial:\n  q: {crank: 0, coupler: 0, rocker: 0}\n"
                              "integrator: {method: rk4, step: 1e-3, t0: 0, t1: 1}\nstabilization: projection\n";
  test::expect_error_mentioning([&] { io::parse_problem(unconstrained, "x"); }, {"stabilization", "has none"});
}

// A projection that cannot reach its tolerance stops the run with the time, the residual and the rows.
TEST(Stabilization, AProjectionThatDoesNotConvergeStopsTheRunAndSaysWhy) {
  const Outcome p = plan_text(example("examples/four_bar/four_bar.yaml") +
                              "\nstabilization: {method: both, tolerance: 1e-300, max_iterations: 3}\n",
                          "four_bar_tight");
  EXPECT_EQ(p.plan.summary.status, IntegrationStatus::NumericalFailure);
  const std::string& m = p.plan.summary.message;
  EXPECT_NE(m.find("did not converge"), std::string::npos) << m;
  EXPECT_NE(m.find("at t = "), std::string::npos) << m;
  EXPECT_NE(m.find("loop"), std::string::npos) << m;  // the rows by name
}

}  // namespace
}  // namespace refdyn
