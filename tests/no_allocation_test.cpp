// No heap allocation in the dynamics and kinematics hot paths, once Data is allocated.
//
// This executable replaces the global operator new/delete (std::string, std::vector, ...) and
// interposes glibc's malloc family (Eigen allocates with malloc, not operator new), counting
// every call. Each test warms up, then calls the functions many times on a preallocated Data
// and asserts that nothing was allocated. Argument checks may build error strings only when
// they fail; the success paths must not allocate.
#include "refdyn/common/error.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

namespace {
std::atomic<long> g_allocations{0};
}

// ---- operator new / delete -------------------------------------------------------------------
// (Every operator new here allocates with malloc, so free is the matching release.)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  ++g_allocations;
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  ++g_allocations;
  return std::malloc(n ? n : 1);
}
void* operator new(std::size_t n, std::align_val_t a) {
  ++g_allocations;
  const std::size_t al = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(al, (n + al - 1) / al * al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return ::operator new(n, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

// ---- malloc family (glibc) -------------------------------------------------------------------
#if defined(__GLIBC__)
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t n) {
  ++g_allocations;
  return __libc_malloc(n);
}
void* calloc(std::size_t k, std::size_t n) {
  ++g_allocations;
  return __libc_calloc(k, n);
}
void* realloc(void* p, std::size_t n) {
  ++g_allocations;
  return __libc_realloc(p, n);
}
void* aligned_alloc(std::size_t al, std::size_t n) {
  ++g_allocations;
  return __libc_memalign(al, n);
}
void* memalign(std::size_t al, std::size_t n) {
  ++g_allocations;
  return __libc_memalign(al, n);
}
int posix_memalign(void** out, std::size_t al, std::size_t n) {
  ++g_allocations;
  void* p = __libc_memalign(al, n);
  if (!p) return 12;  // ENOMEM
  *out = p;
  return 0;
}
}
#endif

using namespace refdyn;

namespace {

struct Case {
  std::string name;
  Model model;
};

std::vector<Case> test_models() {
  std::vector<Case> out;
  out.push_back({"paper manipulator", models::paper_manipulator()});
  std::mt19937 rng(4242);
  // Chains on both sides of the CRBA variants' switch, a long chain, trees with fixed joints,
  // and general (non-z) joint axes.
  for (int n : {2, 7, 30, 140}) {
    test::RandomChainOptions o;
    o.dof = n;
    out.push_back({"chain " + std::to_string(n), build_model(test::random_chain(rng, o))});
  }
  for (int n : {5, 12}) {
    test::RandomChainOptions o;
    o.dof = n;
    o.tree = true;
    o.with_fixed_joints = true;
    ModelDescription d = test::random_chain(rng, o);
    int k = 0;
    for (auto& l : d.links)
      if (l.type != JointType::Fixed && k++ % 2 == 0) l.axis = Vec3(0.3, -0.5, 0.8).normalized();
    out.push_back({"tree " + std::to_string(n), build_model(d)});
  }
  return out;
}

/// Calls every hot-path function once.
void hot_calls(const Model& m, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
               const Eigen::VectorXd& qdd, const Eigen::VectorXd& tau, int point, double& sink) {
  sink += mass_matrix(m, data, q)(0, 0);
  sink += bias_forces(m, data, q, qd)[0];
  sink += gravity_forces(m, data, q)[0];
  sink += inverse_dynamics(m, data, q, qd, qdd)[0];
  sink += forward_dynamics(m, data, q, qd, tau)[0];
  sink += forward_dynamics_crba(m, data, q, qd, tau)[0];
  sink += forward_dynamics_aba(m, data, q, qd, tau)[0];
  forward_kinematics(m, data, q);
  sink += data.oMi[0].p[0];
  point_jacobian(m, data, point);
  sink += data.Jp(0, 0);
  sink += point_drift(m, data, point, qd).drift[0];
  sink += point_position(m, data, point)[0];
  sink += kinetic_energy(m, data, q, qd);
  sink += potential_energy(m, data, q);
}

}  // namespace

TEST(NoAllocation, CounterSeesOperatorNewAndMalloc) {
  long before = g_allocations;
  {
    std::vector<double> v(100);
    v[0] = 1;
    EXPECT_EQ(v[0], 1.0);
  }
  EXPECT_GT(g_allocations - before, 0) << "operator new not counted";
#if defined(__GLIBC__)
  before = g_allocations;
  {
    Eigen::VectorXd v(1000);  // Eigen allocates with malloc
    v.setZero();
    EXPECT_EQ(v[0], 0.0);
  }
  EXPECT_GT(g_allocations - before, 0) << "malloc not counted";
#endif
}

TEST(NoAllocation, DynamicsAndKinematicsHotPaths) {
  const std::vector<Case> cases = test_models();
  std::mt19937 rng(99);
  for (const Case& c : cases) {
    const Model& m = c.model;
    Data data(m);
    const Eigen::VectorXd q = test::random_vector(rng, m.nq, 2.0), qd = test::random_vector(rng, m.nq, 1.0),
                          qdd = test::random_vector(rng, m.nq, 1.0), tau = test::random_vector(rng, m.nq, 5.0);
    const int point = static_cast<int>(m.point_name.size()) - 1;
    ASSERT_GE(point, 0) << c.name;
    double sink = 0;
    hot_calls(m, data, q, qd, qdd, tau, point, sink);  // warm-up
    const long before = g_allocations;
    for (int rep = 0; rep < 20; ++rep) hot_calls(m, data, q, qd, qdd, tau, point, sink);
    const long allocated = g_allocations - before;
    EXPECT_EQ(allocated, 0) << c.name << " (" << m.nq << " DOF)";
    EXPECT_TRUE(std::isfinite(sink)) << c.name;
  }
}

// Each function on its own, so that a failure names the one that allocates.
TEST(NoAllocation, EachFunctionSeparately) {
  const Model m = models::paper_manipulator();
  Data data(m);
  const Eigen::VectorXd q = Eigen::Vector3d(0.3, -0.7, 0.2), qd = Eigen::Vector3d(0.5, 0.1, -0.3),
                        qdd = Eigen::Vector3d(1.0, -2.0, 0.5), tau = Eigen::Vector3d(3.0, 1.0, 20.0);
  const int E = m.point_index("E");
  double sink = 0;
  hot_calls(m, data, q, qd, qdd, tau, E, sink);  // warm-up
  auto count = [&](auto&& f) {
    const long before = g_allocations;
    for (int rep = 0; rep < 5; ++rep) f();
    return g_allocations - before;
  };
  EXPECT_EQ(count([&] { sink += mass_matrix(m, data, q)(0, 0); }), 0) << "mass_matrix";
  EXPECT_EQ(count([&] { sink += bias_forces(m, data, q, qd)[0]; }), 0) << "bias_forces";
  EXPECT_EQ(count([&] { sink += gravity_forces(m, data, q)[0]; }), 0) << "gravity_forces";
  EXPECT_EQ(count([&] { sink += inverse_dynamics(m, data, q, qd, qdd)[0]; }), 0) << "inverse_dynamics";
  EXPECT_EQ(count([&] { sink += forward_dynamics(m, data, q, qd, tau)[0]; }), 0) << "forward_dynamics";
  EXPECT_EQ(count([&] { sink += forward_dynamics_crba(m, data, q, qd, tau)[0]; }), 0) << "forward_dynamics_crba";
  EXPECT_EQ(count([&] { sink += forward_dynamics_aba(m, data, q, qd, tau)[0]; }), 0) << "forward_dynamics_aba";
  EXPECT_EQ(count([&] { forward_kinematics(m, data, q); }), 0) << "forward_kinematics";
  EXPECT_EQ(count([&] { point_jacobian(m, data, E); }), 0) << "point_jacobian";
  EXPECT_EQ(count([&] { sink += point_drift(m, data, E, qd).drift[0]; }), 0) << "point_drift";
  EXPECT_EQ(count([&] { sink += kinetic_energy(m, data, q, qd); }), 0) << "kinetic_energy";
  EXPECT_EQ(count([&] { sink += potential_energy(m, data, q); }), 0) << "potential_energy";
  EXPECT_TRUE(std::isfinite(sink));
}

// The constraints over dual numbers (exact Jacobians, issue 21): evaluate_constraints_dual with
// every ready-made kind and expression constraints of each order allocates nothing once its
// ConstraintEvalDual is built.
TEST(NoAllocation, ConstraintsOverDualNumbers) {
  const Model m = models::paper_manipulator();
  ConstraintSet set;
  set.add(point_on_surface(m, "E", elliptic_cylinder(0.5, 0.3)));
  set.add(point_coordinate(m, "E", 2, sinusoid(0.1, 1.0, 0.0, 0.9)));
  set.add(joint_trajectory(m, m.joint_name[0], polynomial({0.1, 0.2})));
  set.add(joint_coupling(m, m.joint_name[1], m.joint_name[0], 0.5));
  set.add(knife_edge(m, "E", Vec3(0, 1, 0)));
  set.add(point_speed(m, "E", Vec3(1, 0, 0), polynomial({0.3})));
  set.add(expression_constraint(m, "e0", "sin(x(E))*exp(y(E)) + sqrt(1 + z(E)^2) - 2"));
  set.add(expression_constraint(m, "e1", "vx(E)*cos(x(E)) + atan2(vy(E), 2)", true));
  set.add(expression_constraint(m, "e2", "ax(E)*cos(q(" + m.joint_name[0] + ")) + az(E)", ConstraintOrder::Acceleration));
  ConstraintEvalDual ev(m, set);
  std::vector<JacobianScalar> q(m.nv), qd(m.nv);
  for (int i = 0; i < m.nv; ++i) {
    q[i] = JacobianScalar::variable(0.3 * (i + 1), i % kJacobianDirections);
    qd[i] = JacobianScalar::variable(-0.2 * (i + 1), (i + 2) % kJacobianDirections);
  }
  evaluate_constraints_dual(m, set, ev, 0.4, q.data(), qd.data());  // warm-up
  const long before = g_allocations;
  for (int rep = 0; rep < 10; ++rep) evaluate_constraints_dual(m, set, ev, 0.4 + 0.01 * rep, q.data(), qd.data());
  EXPECT_EQ(g_allocations - before, 0);
  for (const JacobianScalar& g : ev.gamma) EXPECT_TRUE(std::isfinite(g.v) && std::isfinite(g.d[0]));
}

// With a seeded time (issue 22: total time derivatives along a motion) and rheonomic rows of
// every kind of time function, expression time functions (their f''' tape) and expression rows
// in t: still nothing allocated after the first call.
TEST(NoAllocation, ConstraintsOverDualNumbersWithASeededTime) {
  const Model m = models::paper_manipulator();
  ConstraintSet set;
  set.add(point_on_surface(m, "E", plane(Vec3(0, 0.2, 1), expression_time_function("0.9 + 0.05*sin(2*t)"))));
  set.add(point_coordinate(m, "E", 0, raised_cosine(0.2, 0.1, 2.0)));
  set.add(joint_trajectory(m, m.joint_name[0], expression_time_function("0.1*t^3 - cos(t)")));
  set.add(point_speed(m, "E", Vec3(1, 0, 0), cycloidal(0.3, 2.0)));
  set.add(expression_constraint(m, "e0", "sin(x(E) + t)*exp(y(E)) - 2*t"));
  set.add(expression_constraint(m, "e1", "vx(E)*cos(t) + atan2(vy(E), 2)", true));
  set.add(expression_constraint(m, "e2", "ax(E)*cos(q(" + m.joint_name[0] + ") + t) + az(E) - sin(t)",
                                ConstraintOrder::Acceleration));
  ConstraintEvalDual ev(m, set);
  std::vector<JacobianScalar> q(m.nv), qd(m.nv);
  for (int i = 0; i < m.nv; ++i) {
    q[i] = JacobianScalar::variable(0.3 * (i + 1), 0, 0.5 - 0.1 * i);  // q ← q̇
    qd[i] = JacobianScalar::variable(-0.2 * (i + 1), 0, 0.3 * i);     // q̇ ← q̈
  }
  auto time = [](double t) { return JacobianScalar::variable(t, 0); };  // t ← 1
  evaluate_constraints_dual(m, set, ev, time(0.4), q.data(), qd.data());  // warm-up
  const long before = g_allocations;
  for (int rep = 0; rep < 10; ++rep) evaluate_constraints_dual(m, set, ev, time(0.4 + 0.01 * rep), q.data(), qd.data());
  EXPECT_EQ(g_allocations - before, 0);
  for (const JacobianScalar& g : ev.gamma) EXPECT_TRUE(std::isfinite(g.v) && std::isfinite(g.d[0]));
}

// The checks still throw (and may allocate then) on bad input: the fast success paths did not
// change what is rejected.
TEST(NoAllocation, ChecksStillRejectBadInput) {
  const Model m = models::paper_manipulator();
  Data data(m);
  const Eigen::VectorXd q = Eigen::Vector3d(0.3, -0.7, 0.2), qd = Eigen::Vector3d::Zero();
  Eigen::VectorXd bad = q;
  bad[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(mass_matrix(m, data, bad), Error);
  EXPECT_THROW(inverse_dynamics(m, data, q, bad, qd), Error);
  EXPECT_THROW(bias_forces(m, data, q, Eigen::VectorXd::Zero(2)), Error);
  EXPECT_THROW(forward_dynamics(m, data, q, qd, bad), Error);
  EXPECT_THROW(forward_dynamics_aba(m, data, bad, qd, q), Error);
  EXPECT_THROW(gravity_forces(m, data, Eigen::VectorXd::Zero(4)), Error);
}
