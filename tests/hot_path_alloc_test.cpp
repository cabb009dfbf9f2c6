// No heap allocation in the planner's and the closed loop's hot paths. Counts calls to malloc
// itself (Eigen allocates with malloc, not operator new), through glibc's __libc_malloc.
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/expression/time_function.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>

extern "C" void* __libc_malloc(size_t);
namespace {
long g_mallocs = 0;
}
extern "C" void* malloc(size_t n) {
  ++g_mallocs;
  return __libc_malloc(n);
}

using namespace refdyn;

TEST(HotPathAllocation, MallocCounterWorks) {
  const long before = g_mallocs;
  Eigen::VectorXd v(1000);
  v.setZero();
  EXPECT_GT(g_mallocs, before);
}

TEST(HotPathAllocation, ReferenceDynamicsDerivativeBothSolvers) {
  models::PaperExample ex;
  for (ReferenceSolver solver : {ReferenceSolver::Projection, ReferenceSolver::Lagrange}) {
    ReferenceDynamicsOptions o = ex.options();
    o.solver = solver;
    ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, o);
    Eigen::VectorXd x = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), dx(x.size());
    rd.derivative(0.0, x, dx);  // warm-up
    const long before = g_mallocs;
    for (int i = 0; i < 50; ++i) rd.derivative(0.01 * i, x, dx);
    EXPECT_EQ(g_mallocs - before, 0) << (solver == ReferenceSolver::Projection ? "projection" : "lagrange");
  }
}

TEST(HotPathAllocation, LargeModelLagrangeAndUnconstrainedRoutes) {
  // 40 DOF: the Lagrange solver's ABA factorization, the projection's orthonormal basis and the
  // unconstrained ABA route.
  std::vector<DHRow> rows(40);
  for (size_t i = 0; i < rows.size(); ++i) {
    rows[i].a = 0.1;
    rows[i].alpha = 0.3 * static_cast<double>(i % 5) - 0.6;
    rows[i].inertia.mass = 1.0;
    rows[i].inertia.com = Vec3(-0.05, 0.01, 0.0);
    rows[i].inertia.I_com = Vec3(0.01, 0.02, 0.02).asDiagonal();
  }
  ModelDescription d = from_dh(rows);
  d.add_point("tip", d.links.back().name, Vec3::Zero());
  const Model model = build_model(d);
  ConstraintSet one_row, four_rows, none;
  one_row.add(point_coordinate(model, "tip", 2, constant(0.1)));
  for (int axis = 0; axis < 3; ++axis) four_rows.add(point_coordinate(model, "tip", axis, constant(0.1)));
  four_rows.add(joint_coupling(model, model.joint_name[1], model.joint_name[0], 0.5));
  const ForceSet forces;
  // The projection of a model this size takes the orthonormal null-space basis (issue 21).
  for (ReferenceSolver solver : {ReferenceSolver::Lagrange, ReferenceSolver::Projection}) {
    ReferenceDynamicsOptions o;
    o.solver = solver;
    for (const ConstraintSet* set : {&one_row, &four_rows, &none}) {
      ReferenceDynamics rd(model, forces, *set, o);
      Eigen::VectorXd x = rd.make_state(Eigen::VectorXd::Constant(40, 0.2), Eigen::VectorXd::Constant(40, 0.1));
      Eigen::VectorXd dx(x.size());
      rd.derivative(0.0, x, dx);  // warm-up (the projection chooses its partition here)
      const long before = g_mallocs;
      for (int i = 0; i < 10; ++i) rd.derivative(0.01 * i, x, dx);
      EXPECT_EQ(g_mallocs - before, 0) << set->rows() << " rows, "
                                       << (solver == ReferenceSolver::Projection ? "projection" : "lagrange");
    }
  }
}

TEST(HotPathAllocation, ControllerAndDynamics) {
  models::PaperExample ex;
  ComputedTorquePD ctrl(ex.model, Eigen::Vector3d(40, 3, 60));
  Data data(ex.model);
  Eigen::VectorXd q = ex.q0(), qd = Eigen::VectorXd::Constant(3, 0.3), qdd = Eigen::VectorXd::Constant(3, 0.1);
  Eigen::VectorXd tau(3);
  const ReferenceSample ref{q, qd, qdd};
  ctrl.compute(0, q, qd, ref, tau);
  forward_dynamics(ex.model, data, q, qd, tau);
  const long before = g_mallocs;
  for (int i = 0; i < 20; ++i) {
    ctrl.compute(0, q, qd, ref, tau);
    forward_dynamics(ex.model, data, q, qd, tau);
    forward_dynamics_aba(ex.model, data, q, qd, tau);
    mass_matrix(ex.model, data, q);
    bias_forces(ex.model, data, q, qd);
    inverse_dynamics(ex.model, data, q, qd, qdd);
  }
  EXPECT_EQ(g_mallocs - before, 0);
}

// A recorded motion stores each series in one buffer (SampleSeries): a plan and a closed-loop
// run twice as long make a handful more allocations (buffer growth), not one per sample and series.
TEST(HotPathAllocation, RecordingAllocatesPerSeriesNotPerSample) {
  models::PaperExample ex;
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  ComputedTorquePD ctrl(ex.model, Eigen::Vector3d(40, 3, 60));
  const Eigen::VectorXd x0 = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3));
  long plan_mallocs[2], run_mallocs[2];
  size_t samples[2];
  for (int i = 0; i < 2; ++i) {
    IntegratorOptions io;
    io.t0 = 0, io.t1 = 0.25 * (i + 1), io.step = 1e-3;
    long before = g_mallocs;
    const Plan plan = plan_motion(rd, x0, {io});
    plan_mallocs[i] = g_mallocs - before;
    ASSERT_TRUE(plan.summary.ok()) << plan.summary.message;
    samples[i] = plan.size();
    ClosedLoopOptions o;
    o.integrator = io;
    before = g_mallocs;
    const ClosedLoopResult run = simulate_closed_loop(ex.model, ex.forces, ctrl, plan, nullptr, plan.x.front(), o);
    run_mallocs[i] = g_mallocs - before;
    ASSERT_TRUE(run.summary.ok()) << run.summary.message;
    ASSERT_EQ(run.size(), plan.size());
  }
  ASSERT_EQ(samples[1], 2 * samples[0] - 1);  // 251 and 501 samples
  std::printf("mallocs: plan %ld then %ld, closed loop %ld then %ld (samples %zu then %zu)\n", plan_mallocs[0],
              plan_mallocs[1], run_mallocs[0], run_mallocs[1], samples[0], samples[1]);
  // One allocation per sample and series would add 250 × (8 plan series, 4 run series).
  EXPECT_LT(plan_mallocs[1] - plan_mallocs[0], 40) << plan_mallocs[0] << " then " << plan_mallocs[1];
  EXPECT_LT(run_mallocs[1] - run_mallocs[0], 40) << run_mallocs[0] << " then " << run_mallocs[1];
}
