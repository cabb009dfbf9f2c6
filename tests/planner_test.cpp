// The planner interface (simulate/planner.hpp): a problem of order ≤ 2 (an acceleration-level
// row) and a jerk problem planned through Problem::make_planner / plan_problem(Planner&) record
// the same series, bit for bit, as the direct plan_motion and plan_jerk_motion calls; the
// planners report what the callers need (state, names, partition, residuals); a Dormand–Prince
// closed loop given the Planner equals the one given the ReferenceDynamics.
#include "refdyn/io/scenario.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/simulate/planner.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

using namespace refdyn;

namespace {

// A bead on a rotating arm: the tangential acceleration (order 2) or jerk (order 3) prescribed.
const char* kParticle = R"(
name: particle
parameters: {m: 1.7, J: 0.9, w: 2.0}
model:
  gravity: [0, 0, -9.81]
  links:
    - {name: arm, joint: th, parent: base, type: revolute, axis: [0, 0, 1], mass: 0, inertia: [0, 0, 0]}
    - {name: bead, joint: r, parent: arm, type: prismatic, axis: [1, 0, 0], mass: m, inertia: [0, 0, 0]}
  points:
    P: {link: bead, position: [0, 0, 0]}
forces:
  - {type: damping, joint: r, coefficient: 0.2}
constraints:
@CONSTRAINT@
@EXTRA@
initial:
  q: {th: 0, r: 1}
  qd: {th: 0.8, r: 0.3}
@QDD@
integrator: {method: rk4, step: 0.01, t0: 0, t1: 2}
)";

std::string particle(bool jerk) {
  std::string y = kParticle;
  auto put = [&](const std::string& k, const std::string& v) { y.replace(y.find(k), k.size(), v); };
  put("@CONSTRAINT@", jerk ? "  - name: tangential\n    order: jerk\n"
                             "    expression: (vx(P)*jx(P) + vy(P)*jy(P))/sqrt(vx(P)^2 + vy(P)^2) - J*sin(w*t)"
                           : "  - name: tangential\n    order: acceleration\n"
                             "    expression: (vx(P)*ax(P) + vy(P)*ay(P))/sqrt(vx(P)^2 + vy(P)^2) - J*sin(w*t)");
  put("@EXTRA@", jerk ? "baumgarte: {kappa: 40}" : "");
  put("@QDD@", jerk ? "  qdd: {th: -0.16, r: 0.76}" : "");
  return y;
}

bool same_bits(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return a.size() == b.size() && (a.size() == 0 || std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0);
}

void expect_same_series(const SampleSeries& a, const SampleSeries& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t k = 0; k < a.size(); ++k) ASSERT_TRUE(same_bits(a[k], b[k])) << what << " differs at sample " << k;
}

void expect_same_plan(const Plan& a, const Plan& b) {
  EXPECT_EQ(a.joints, b.joints);
  EXPECT_EQ(a.state_names, b.state_names);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.constraint_rows, b.constraint_rows);
  EXPECT_EQ(a.material_row, b.material_row);
  EXPECT_EQ(a.target_signals, b.target_signals);
  EXPECT_EQ(a.force_signals, b.force_signals);
  ASSERT_EQ(a.t.size(), b.t.size());
  EXPECT_EQ(0, std::memcmp(a.t.data(), b.t.data(), sizeof(double) * a.t.size()));
  expect_same_series(a.x, b.x, "x");
  expect_same_series(a.qdd, b.qdd, "qdd");
  expect_same_series(a.point_positions, b.point_positions, "points");
  expect_same_series(a.targets, b.targets, "targets");
  expect_same_series(a.forces, b.forces, "force signals");
  expect_same_series(a.phi, b.phi, "phi");
  expect_same_series(a.phid, b.phid, "phid");
  expect_same_series(a.lambda, b.lambda, "lambda");
  expect_same_series(a.Qc, b.Qc, "Qc");
  expect_same_series(a.actuator_effort, b.actuator_effort, "actuator effort");
  expect_same_series(a.reaction_effort, b.reaction_effort, "reaction effort");
  EXPECT_EQ(a.summary.status, b.summary.status);
  EXPECT_EQ(a.summary.steps, b.summary.steps);
  EXPECT_EQ(a.summary.t_end, b.summary.t_end);
  EXPECT_EQ(a.summary.max_constraint_residual, b.summary.max_constraint_residual);
  EXPECT_EQ(a.stages.steps, b.stages.steps);
  EXPECT_EQ(a.stages.data, b.stages.data);
}

TEST(Planner, OrderTwoPlansLikePlanMotion) {
  const auto p = io::parse_problem(particle(false), "particle.yaml");
  ASSERT_FALSE(p->is_jerk_problem());
  EXPECT_EQ(p->constraints.row_order(0), 2);
  const auto planner = p->make_planner();
  ASSERT_NE(dynamic_cast<ReferencePlanner*>(planner.get()), nullptr);
  const Plan a = plan_problem(*p, *planner);
  ASSERT_TRUE(a.summary.ok()) << a.summary.message;
  ASSERT_GT(a.size(), 100u);

  ReferenceDynamics rd(p->model, p->forces, p->constraints, p->options);
  RecordOptions record{p->report_point_indices()};
  record.residual_tolerance = p->residual_tolerance;
  const Plan b = plan_motion(rd, rd.make_state(p->q0, p->qd0), {p->integrator, p->residual_from, record});
  expect_same_plan(a, b);
  EXPECT_GT(a.stages.data.size(), 0u);

  // What the callers read from the interface.
  EXPECT_EQ(planner->state_size(), rd.state_size());
  EXPECT_EQ(planner->state_names(), a.state_names);
  EXPECT_FALSE(planner->state_has_acceleration());
  EXPECT_TRUE(planner->checks_residual_tolerance());
  EXPECT_TRUE(planner->description().empty());
  const Eigen::VectorXd x = p->initial_state(*planner);
  EXPECT_TRUE(same_bits(x, a.x.front()));
  Eigen::VectorXd dx(x.size());
  planner->derivative(0.0, x, dx);
  const std::optional<PlannerPartition> part = planner->partition();
  ASSERT_TRUE(part.has_value());
  EXPECT_EQ(part->independent.size() + part->dependent.size(), 2u);
  const std::vector<RowResidual> res = planner->row_residuals();
  ASSERT_EQ(res.size(), 2u);
  EXPECT_EQ(res[0].label, "|Phi|");
  EXPECT_LT(res[0].values.maxCoeff(), 1e-12);
  const double *q = nullptr, *qd = nullptr, *qdd = nullptr;
  planner->reference(x, dx, q, qd, qdd);
  EXPECT_TRUE(same_bits(Eigen::Map<const Eigen::VectorXd>(qdd, 2), a.qdd.front()));
  EXPECT_EQ(q, x.data());
  EXPECT_EQ(qd, x.data() + 2);
}

TEST(Planner, JerkPlansLikePlanJerkMotion) {
  const auto p = io::parse_problem(particle(true), "particle_jerk.yaml");
  ASSERT_TRUE(p->is_jerk_problem());
  const auto planner = p->make_planner();
  ASSERT_NE(dynamic_cast<JerkPlanner*>(planner.get()), nullptr);
  const Plan a = plan_problem(*p, *planner);
  ASSERT_TRUE(a.summary.ok()) << a.summary.message;
  ASSERT_GT(a.size(), 100u);

  JerkDynamics jd(p->model, p->jerk_constraints, JerkDynamicsOptions{40.0}, &p->forces);
  const Eigen::VectorXd x0 = jd.initial_state(0.0, p->q0, p->qd0, &p->qdd0);
  const Plan b = plan_jerk_motion(jd, x0, {p->integrator, 0.0, RecordOptions{p->report_point_indices()}});
  expect_same_plan(a, b);
  // The old entry point (a ReferenceDynamics that a jerk problem does not use) plans the same.
  const auto rd = p->make_reference_dynamics();
  expect_same_plan(plan_problem(*p, *rd), b);

  EXPECT_EQ(planner->state_size(), 6);
  EXPECT_EQ(planner->state_names(), (std::vector<std::string>{"acc_th", "acc_r"}));
  EXPECT_EQ(planner->state_names(), a.state_names);
  EXPECT_TRUE(planner->state_has_acceleration());
  EXPECT_FALSE(planner->checks_residual_tolerance());
  EXPECT_FALSE(planner->partition().has_value());
  EXPECT_EQ(planner->description(), "jerk-level problem (p = 3): state [q; qd; qdd], kappa = 40 1/s; no partition: a "
                                    "KKT system with the mass matrix (partition: is not used)");
  EXPECT_FALSE(std::isfinite(p->residual_tolerance));  // not checked: summary.json writes null
  const Eigen::VectorXd x = p->initial_state(*planner);
  EXPECT_TRUE(same_bits(x, x0));
  Eigen::VectorXd dx(x.size());
  planner->derivative(0.0, x, dx);
  const std::vector<RowResidual> res = planner->row_residuals();
  ASSERT_EQ(res.size(), 1u);
  EXPECT_EQ(res[0].label, "|B qddd + s|");
  EXPECT_LT(res[0].values.maxCoeff(), 1e-12);
  // q̂̈ from the derivative is the state's q̈ (ẋ = [q̇; q̈; q⃛]).
  const double *q = nullptr, *qd = nullptr, *qdd = nullptr;
  planner->reference(x, dx, q, qd, qdd);
  EXPECT_TRUE(same_bits(Eigen::Map<const Eigen::VectorXd>(qdd, 2), x.segment(4, 2)));
}

// Dormand–Prince integrates the reference jointly with the plant: through the Planner and
// through the ReferenceDynamics overload, the same run.
TEST(Planner, ClosedLoopThroughThePlannerEqualsTheReferenceDynamicsRoute) {
  const auto p = io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/tests/data/good/sweep_arm.yaml");
  ASSERT_EQ(p->integrator.method, IntegratorMethod::DormandPrince45);
  const auto planner = p->make_planner();
  const Plan plan = plan_problem(*p, *planner);
  ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
  const Experiment& ex = *p->experiments.front();
  auto planner_b = p->make_planner();
  const ClosedLoopResult a = track_experiment(*p, ex, plan, *planner_b);
  const auto rd = p->make_reference_dynamics();
  const ClosedLoopResult b = track_experiment(*p, ex, plan, *rd);
  ASSERT_TRUE(a.summary.ok()) << a.summary.message;
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.t, b.t);
  expect_same_series(a.x, b.x, "x");
  expect_same_series(a.tau, b.tau, "tau");
  expect_same_series(a.q_ref, b.q_ref, "q_ref");
  expect_same_series(a.qd_ref, b.qd_ref, "qd_ref");
}

}  // namespace
