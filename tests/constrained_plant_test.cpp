// Tracking on the machine as built (simulate/closed_loop.hpp, simulate/actuation.hpp): the plant
// keeps its material constraints, only the actuated joints receive effort, the controllers act on
// the reduced dynamics. Oracles: the closed-form error of computed torque, the constraints'
// residuals, zero effort at passive joints, the exact Jacobian against finite differences.
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/closed_loop.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace refdyn {
namespace {

std::unique_ptr<Problem> example(const std::string& rel) {
  return io::load_problem(std::string(REFDYN_SOURCE_DIR) + "/examples/" + rel);
}

io::Results track(const Problem& p) {
  io::RunOptions o;
  o.track = true;
  return io::run_problem(p, o);
}

int joint(const Model& m, const std::string& name) {
  return static_cast<int>(std::find(m.joint_name.begin(), m.joint_name.end(), name) - m.joint_name.begin());
}

// Four-bar, the crank its only motor, computed torque with δ = 10, the crank started 0.05 rad
// off with ė0 = 0: e(t) = 0.05 (1 + δt) e^(−δt); the rocker tip stays on its ground pivot; the
// coupler and rocker receive no effort.
TEST(ConstrainedPlant, FourBarCrankErrorFollowsTheClosedFormWithOneMotor) {
  const auto p = example("four_bar/four_bar.yaml");
  ASSERT_TRUE(p->material);
  EXPECT_EQ(p->actuation.actuated, std::vector<int>{joint(p->model, "crank")});
  EXPECT_EQ(p->actuation.independent, std::vector<int>{joint(p->model, "crank")});
  const io::Results r = track(*p);
  ASSERT_EQ(r.runs.size(), 1u);
  const ClosedLoopResult& run = r.runs[0].result;
  ASSERT_TRUE(run.summary.ok()) << run.summary.message;
  EXPECT_NEAR(run.t.back(), 2.0, 1e-12);
  const Model& m = p->model;
  const int crank = joint(m, "crank"), coupler = joint(m, "coupler"), rocker = joint(m, "rocker");
  const int T = static_cast<int>(std::find(m.point_name.begin(), m.point_name.end(), "T") - m.point_name.begin());
  const Vec3 D(0.4, 0, 0);
  Data kin(m);
  double worst_e = 0, worst_tip = 0;
  for (size_t k = 0; k < run.t.size(); ++k) {
    const double t = run.t[k], delta = 10;
    const double e = run.x[k][crank] - run.q_ref[k][crank];
    worst_e = std::max(worst_e, std::abs(e - 0.05 * (1 + delta * t) * std::exp(-delta * t)));
    ASSERT_EQ(run.tau[k][coupler], 0.0) << "t = " << t;
    ASSERT_EQ(run.tau[k][rocker], 0.0) << "t = " << t;
    forward_kinematics(m, kin, run.x[k].head(m.nq));
    worst_tip = std::max(worst_tip, (point_position(m, kin, T) - D).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst_e, 1e-6);
  EXPECT_LT(worst_tip, 1e-8);
  EXPECT_LT(run.max_material_residual, 1e-8);
  EXPECT_GT(run.initial_correction_q, 1e-3);  // coupler and rocker were solved for the crank's error
  // The reactions of the loop closure are recorded, and they are what holds the passive joints.
  ASSERT_EQ(run.reaction_effort.size(), run.t.size());
  EXPECT_GT(run.reaction_effort[run.t.size() / 2].cwiseAbs().maxCoeff(), 1e-3);
  // The summary and sweep.csv carry them.
  EXPECT_EQ(r.runs[0].summary.max_material_residual, run.max_material_residual);
  EXPECT_NE(io::sweep_csv(*p, r).find("max_material_residual"), std::string::npos);
}

// Knife edge from a heading error: the blade never slides sideways; the independent coordinates
// (x, θ) follow the closed form.
TEST(ConstrainedPlant, UnicycleNeverSlidesSideways) {
  const auto p = example("unicycle/unicycle.yaml");
  const io::Results r = track(*p);
  ASSERT_EQ(r.runs.size(), 1u);
  const ClosedLoopResult& run = r.runs[0].result;
  ASSERT_TRUE(run.summary.ok()) << run.summary.message;
  const Model& m = p->model;
  const int x = joint(m, "x"), y = joint(m, "y"), th = joint(m, "theta");
  EXPECT_EQ(p->actuation.independent, (std::vector<int>{x, th}));
  double worst_lateral = 0, worst_e = 0;
  const double e0 = run.x[0][th] - run.q_ref[0][th], ed0 = run.x[0][m.nq + th] - run.qd_ref[0][th];
  for (size_t k = 0; k < run.t.size(); ++k) {
    const Eigen::VectorXd& s = run.x[k];
    worst_lateral = std::max(worst_lateral, std::abs(-std::sin(s[th]) * s[m.nq + x] + std::cos(s[th]) * s[m.nq + y]));
    const double t = run.t[k], d = 4;
    const double e = s[th] - run.q_ref[k][th];
    worst_e = std::max(worst_e, std::abs(e - (e0 + (ed0 + d * e0) * t) * std::exp(-d * t)));
  }
  EXPECT_LT(worst_lateral, 1e-8);
  EXPECT_LT(worst_e, 1e-6);
}

// Gear pair: the wheel is passive (exactly zero effort) and turns with the pinion.
TEST(ConstrainedPlant, GearPairDrivesThePassiveWheelThroughTheTeeth) {
  const auto p = example("gear_pair/gear_pair.yaml");
  const io::Results r = track(*p);
  const ClosedLoopResult& run = r.runs[0].result;
  ASSERT_TRUE(run.summary.ok()) << run.summary.message;
  const int pinion = joint(p->model, "pinion"), wheel = joint(p->model, "wheel");
  double worst = 0;
  for (size_t k = 0; k < run.t.size(); ++k) {
    ASSERT_EQ(run.tau[k][wheel], 0.0);
    worst = std::max(worst, std::abs(run.x[k][wheel] + 0.5 * run.x[k][pinion]));
  }
  EXPECT_LT(worst, 1e-8);
  EXPECT_GT(run.tau[run.t.size() / 2].cwiseAbs().maxCoeff(), 1e-3);  // the motor holds the arm
}

// Motors at every joint and no material rows: the controllers' laws are the unconstrained ones,
// to the bit (the paper's study depends on it).
TEST(ConstrainedPlant, FullActuationWithoutMaterialRowsIsTheUnconstrainedLaw) {
  const auto p = example("paper/paper.yaml");
  EXPECT_FALSE(p->material);
  EXPECT_TRUE(p->actuation.trivial(p->model));
}

// The closed loop's exact Jacobian on a constrained plant (BDF) against central differences.
TEST(ConstrainedPlant, ClosedLoopJacobianOnTheFourBarMatchesFiniteDifferences) {
  const auto p = example("four_bar/four_bar.yaml");
  auto planner = p->make_planner();
  std::unique_ptr<Controller> c = p->experiments[0]->make_controller(p->model);
  ClosedLoopOptions o;
  o.material = p->material.get();
  o.plant = p->options;
  const int n = p->model.nv, nr = planner->state_size();
  Eigen::VectorXd X(nr + 2 * n);
  X.head(nr) = p->initial_state(*planner);
  X.segment(nr, n) = X.head(n) + Eigen::Vector3d(0.02, -0.01, 0.015);
  X.segment(nr + n, n) = X.segment(n, n) + Eigen::Vector3d(0.1, 0.2, -0.1);
  Eigen::VectorXd dX;
  Eigen::MatrixXd J;
  closed_loop_derivative(p->model, ForceSet(), *c, *planner, o, 0.3, X, dX, &J);
  Eigen::MatrixXd Jfd(X.size(), X.size());
  for (int i = 0; i < X.size(); ++i) {
    const double h = 1e-6 * std::max(1.0, std::abs(X[i]));
    Eigen::VectorXd a = X, b = X, da, db;
    a[i] += h;
    b[i] -= h;
    closed_loop_derivative(p->model, ForceSet(), *c, *planner, o, 0.3, a, da);
    closed_loop_derivative(p->model, ForceSet(), *c, *planner, o, 0.3, b, db);
    Jfd.col(i) = (da - db) / (2 * h);
  }
  EXPECT_TRUE(test::near(J, Jfd, 1e-6, 1e-5));
}

// The controller on the constrained plant, two routes: reading the plant's own evaluation at the
// state (M, c + g and the material rows of ReferenceDynamics::prepare_derivative, what the closed
// loop passes, with and without the plant's factored partition) and evaluating everything itself
// (RNEA for M q̈* + c + g, the rows again, K_dc solved again). The computed-torque efforts agree
// to rounding, at states on and off the constraints.
TEST(ConstrainedPlant, ControllerReadingThePlantsEvaluationEqualsItsOwn) {
  const auto p = example("four_bar/four_bar.yaml");
  auto planner = p->make_planner();
  std::unique_ptr<Controller> c = p->experiments[0]->make_controller(p->model);
  ForceSet none;
  ReferenceDynamics rd(p->model, none, *p->material, p->options);
  const int n = p->model.nv;
  const Eigen::VectorXd x0 = p->initial_state(*planner).head(2 * n);
  const Eigen::VectorXd qr = x0.head(n), qdr = x0.tail(n), qddr = Eigen::Vector3d(0.3, -0.2, 0.1);
  const ReferenceSample ref{qr, qdr, qddr};
  int compared = 0;
  for (const double off : {0.0, 0.01, -0.03}) {
    Eigen::VectorXd x = x0, xdot(x0.size());
    x.head(n) += off * Eigen::Vector3d(1.0, -0.5, 0.7);
    x.tail(n) += off * Eigen::Vector3d(2.0, 1.0, -1.0);
    rd.prepare_derivative(0.2, x, xdot);
    ASSERT_TRUE(rd.mass_filled());
    ASSERT_TRUE(rd.partition_factored());
    PlantRows rows_only, factored;
    rows_only.rows = factored.rows = &rd.constraints();
    factored.independent = &rd.independent(), factored.dependent = &rd.dependent();
    factored.Kinv = &rd.partition_inverse(), factored.G = &rd.partition_g();
    Eigen::VectorXd shared, with_rows, own;
    c->compute(0.2, x.head(n), x.tail(n), ref, nullptr, nullptr, shared, &p->model, &rd.data(), &factored);
    c->compute(0.2, x.head(n), x.tail(n), ref, nullptr, nullptr, with_rows, &p->model, &rd.data(), &rows_only);
    c->compute(0.2, x.head(n), x.tail(n), ref, nullptr, nullptr, own);
    EXPECT_TRUE(test::near(shared, own, 1e-12, 1e-12)) << "offset " << off << "\n" << shared.transpose() << "\n"
                                                       << own.transpose();
    EXPECT_TRUE(test::near(with_rows, own, 1e-12, 1e-12)) << "offset " << off;
    EXPECT_GT(own.norm(), 0.0);
    ++compared;
  }
  EXPECT_EQ(compared, 3);
}

// BDF on the constrained plant reaches the same closed loop as RK4.
TEST(ConstrainedPlant, ImplicitIntegrationOfTheFourBarPlantAgreesWithRk4) {
  std::string text = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/examples/four_bar/four_bar.yaml");
  const auto a = io::parse_problem(text, "four_bar.yaml");
  const std::string from = "integrator: {method: rk4, step: 1e-3, t0: 0, t1: 2}";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "integrator: {method: bdf, step: 1e-3, t0: 0, t1: 1, rtol: 1e-10, atol: 1e-12}");
  const auto b = io::parse_problem(text, "four_bar_bdf.yaml");
  const io::Results ra = track(*a), rb = track(*b);
  const ClosedLoopResult &x = ra.runs[0].result, &y = rb.runs[0].result;
  ASSERT_TRUE(y.summary.ok()) << y.summary.message;
  EXPECT_GT(y.summary.jacobian_evaluations, 0);
  // Compare at t = 1 s.
  size_t k = 0;
  while (k < x.t.size() && x.t[k] < 1.0 - 1e-9) ++k;
  ASSERT_LT(k, x.t.size());
  EXPECT_TRUE(test::near(y.x.back().head(6), x.x[k].head(6), 1e-6, 1e-7));
}

// Bad input: one located error, nothing run.
std::string four_bar_with(const std::string& from, const std::string& to) {
  std::string text = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/examples/four_bar/four_bar.yaml");
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

::testing::AssertionResult mentions(const std::string& msg, std::initializer_list<const char*> parts) {
  for (const char* p : parts)
    if (msg.find(p) == std::string::npos) return ::testing::AssertionFailure() << "'" << msg << "' lacks '" << p << "'";
  return ::testing::AssertionSuccess();
}

std::string error_of(const std::string& text) {
  try {
    io::parse_problem(text, "four_bar.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ConstrainedPlant, BadActuatorsAndGainsAreLocatedErrors) {
  EXPECT_TRUE(mentions(error_of(four_bar_with("actuators: [crank]", "actuators: [crnk]")),
                       {"four_bar.yaml:", "actuators[0]", "crank"}));
  EXPECT_TRUE(mentions(error_of(four_bar_with("actuators: [crank]", "actuators: [crank, crank]")), {"listed twice"}));
  EXPECT_TRUE(mentions(error_of(four_bar_with("actuators: [crank]", "actuators: []")), {"empty list"}));
  EXPECT_TRUE(mentions(error_of(four_bar_with("delta: {crank: 10}", "delta: {crank: 10, rocker: 3}")),
                       {"controller.delta.rocker", "does not assign", "crank"}));
  EXPECT_TRUE(mentions(error_of(four_bar_with("delta: {crank: 10}", "delta: {rocker: 10}")), {"does not assign"}));
  EXPECT_TRUE(mentions(error_of(four_bar_with("delta: {crank: 10}", "delta: [10, 10, 10]")), {"expected 1 values"}));
  // Two motors for one independent coordinate is fine (least-norm efforts); the coordinate is then
  // chosen by conditioning and may switch along the run, so each coordinate needs a gain.
  const std::string two_motors = four_bar_with("actuators: [crank]", "actuators: [crank, rocker]");
  EXPECT_TRUE(mentions(error_of(two_motors), {"missing a value for joint 'coupler'"}));
  std::string ok = two_motors;
  ok.replace(ok.find("delta: {crank: 10}"), 18, "delta: {crank: 10, coupler: 10, rocker: 10}");
  EXPECT_EQ(error_of(ok), "");
}

// An unconstrained two-link arm with a motor at one joint cannot be tracked by these laws: the
// message names the coordinate no motor reaches.
TEST(ConstrainedPlant, TooFewMotorsIsALoadError) {
  std::string text = test::read_file(std::string(REFDYN_SOURCE_DIR) + "/examples/planar_2r_circle/sweeps.yaml");
  text += "\nactuators: [q1]\n";
  std::string msg;
  try {
    io::parse_problem(text, "sweeps.yaml");
  } catch (const Error& e) {
    msg = e.what();
  }
  EXPECT_TRUE(mentions(msg, {"actuators", "1 motor", "q2"}));
}

// A start that the machine cannot have (the crank's error puts the rocker tip out of reach of
// its pivot) is that run's failure with its reason, never a crash.
TEST(ConstrainedPlant, AnImpossibleStartIsTheRunsFailure) {
  // A three-link arm (1 m links) whose tip is pinned at (2.5, 0): with the first joint at π the
  // elbow is 3.5 m from the pin, out of reach of the other two links.
  const std::string yaml = R"(
name: pinned
model:
  gravity: [0, -9.81, 0]
  links:
    - {name: l1, joint: j1, parent: base, type: revolute, axis: [0, 0, 1], mass: 1, com: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
    - {name: l2, joint: j2, parent: l1, type: revolute, axis: [0, 0, 1], origin: {xyz: [1, 0, 0]}, mass: 1, com: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
    - {name: l3, joint: j3, parent: l2, type: revolute, axis: [0, 0, 1], origin: {xyz: [1, 0, 0]}, mass: 1, com: [0.5, 0, 0], inertia: [0.01, 0.1, 0.1]}
  points:
    tip: {link: l3, position: [1, 0, 0]}
    pin: {link: world, position: [2.5, 0, 0]}
constraints:
  - {name: pinned, origin: material, kind: points_coincide, points: [tip, pin], axes: [x, y]}
  - {name: drive, origin: programmed, kind: joint_trajectory, joint: j1, function: 0.1*sin(t)}
partition: {independent: []}
initial:
  q: {j1: 0, j2: -0.7227342478134157, j3: 1.4454684956268313}
  qd: {j1: 0.1, j2: 0, j3: 0}
  consistency: project
integrator: {method: rk4, step: 1e-3, t0: 0, t1: 0.1}
actuators: [j1]
controller: {type: computed_torque_pd, delta: {j1: 10}}
experiments:
  - name: impossible
    initial: {q: {j1: 3.14159}}
)";
  const auto p = io::parse_problem(yaml, "pinned.yaml");
  const io::Results r = track(*p);
  ASSERT_EQ(r.runs.size(), 1u);
  EXPECT_EQ(r.runs[0].summary.status, IntegrationStatus::NumericalFailure);
  EXPECT_TRUE(mentions(r.runs[0].summary.message, {"cannot satisfy the material constraints"}));
}

}  // namespace
}  // namespace refdyn
