// No heap allocation in the planner's and the closed loop's hot paths. Counts calls to malloc
// itself (Eigen allocates with malloc, not operator new), through glibc's __libc_malloc.
#include "refdyn/control.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/recursive_dynamics.hpp"

#include <gtest/gtest.h>

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
