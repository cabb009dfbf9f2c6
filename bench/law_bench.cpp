// The constraint kinds and force elements evaluated alone (issue 35: each law written once over a
// scalar; the double, dual and rate paths are its instantiations): one call of
//   evaluate_constraints       (double: Φ, Φ̇, A, γ with the point kinematics)
//   evaluate_constraints_dual  (Dual<8>, one sweep)
//   ForceSet::evaluate         (double Q and ż; with ∂Q/∂q̇ for the paper-literal option)
//   ForceSet::evaluate_dual    (Dual<8>)
//   add_rate_with_states       (the jerk level's Q̇ of every element)
// on the paper's arm (its two programmed constraints, LuGre in three joints and the flexible
// drive) and on a 5-DOF chain with one constraint of every ready-made kind and one of each
// force element. Times: CPU time per call, median of the repetitions (bench/README.md).
//   law_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/multibody/kinematics.hpp"

#include <benchmark/benchmark.h>

#include <memory>

using namespace refdyn;

namespace {

struct Setup {
  explicit Setup(Model m) : model(std::move(m)) {}
  Model model;
  ConstraintSet constraints;
  ForceSet forces;
  Eigen::VectorXd q, qd, qdd, z, zdot;
  double t = 0.7;
};

std::unique_ptr<Setup> paper() {
  static models::PaperExample ex;
  auto s = std::make_unique<Setup>(ex.model);
  s->constraints = ex.constraints;
  s->forces = ex.forces;
  s->q = ex.q0();
  s->qd = Eigen::Vector3d(0.1, -0.2, 0.05);
  s->qdd = Eigen::Vector3d(0.3, 0.4, -0.2);
  s->z = Eigen::Vector3d(1e-3, -2e-3, 1e-4);
  s->zdot = Eigen::Vector3d(0.01, 0.02, -0.01);
  return s;
}

/// A spatial 5-DOF chain (revolute, revolute, prismatic, revolute, revolute) with two points.
Model chain5() {
  ModelDescription d;
  auto link = [&](const char* name, int parent, JointType type, const Vec3& axis, const Vec3& at, double mass,
                  const Vec3& com) {
    LinkSpec l;
    l.name = name;
    l.joint_name = std::string("j") + name[1];
    l.parent = parent;
    l.type = type;
    l.axis = axis;
    l.placement.p = at;
    l.inertia.mass = mass;
    l.inertia.com = com;
    l.inertia.I_com = Vec3(0.02, 0.03, 0.01).asDiagonal();
    d.add_link(l);
  };
  link("l1", -1, JointType::Revolute, Vec3::UnitZ(), Vec3::Zero(), 1.5, Vec3(0, 0, 0.2));
  link("l2", 0, JointType::Revolute, Vec3::UnitY(), Vec3(0, 0, 0.4), 1.2, Vec3(0.2, 0, 0));
  link("l3", 1, JointType::Prismatic, Vec3::UnitX(), Vec3(0.4, 0, 0), 0.8, Vec3(0.1, 0, 0));
  link("l4", 2, JointType::Revolute, Vec3(1, 1, 0).normalized(), Vec3(0.2, 0, 0), 0.5, Vec3(0.05, 0, 0));
  link("l5", 3, JointType::Revolute, Vec3::UnitZ(), Vec3(0.1, 0, 0), 0.2, Vec3(0.03, 0, 0));
  d.add_point("E", "l5", Vec3(0.1, 0, 0));
  d.add_point("F", "l3", Vec3(0.05, 0.02, 0));
  return build_model(d);
}

std::unique_ptr<Setup> every_kind() {
  auto s = std::make_unique<Setup>(chain5());
  const Model& m = s->model;
  ConstraintSet& c = s->constraints;
  c.add(point_on_surface(m, "E", elliptic_cylinder(0.5, 0.3, 0.1, 0.0)));
  auto sph = point_on_surface(m, "F", sphere(Vec3(0.1, 0.0, 0.2), 0.6));
  sph->name = "F_on_sphere";
  c.add(sph);
  c.add(point_coordinate(m, "E", 2, sinusoid(0.1, 1.3, 0.2, 0.5)));
  c.add(joint_trajectory(m, "j1", cycloidal(1.0, 2.0)));
  c.add(joint_coupling(m, "j5", "j4", 0.5, 0.1));
  c.add(points_coincide(m, "E", "F", {0, 1}));
  c.add(knife_edge(m, "E", Vec3(0, 1, 0)));
  c.add(point_speed(m, "F", Vec3(1, 0, 0), raised_cosine(0.0, 0.2, 3.0)));
  c.add(expression_constraint(m, "expr0", "(x(E) - 0.1)^2 + sin(q(j2))*y(F) - 0.3 + 0.1*t", ConstraintOrder::Position));
  c.add(expression_constraint(m, "expr1", "x(E)*vy(E) - y(E)*vx(E) + 0.2*qd(j3) - 0.05", ConstraintOrder::Velocity));
  c.add(expression_constraint(m, "expr2", "ax(E) + cos(q(j1))*qdd(j2) + vx(F)^2 - 0.1", ConstraintOrder::Acceleration));
  ForceSet& f = s->forces;
  f.add(joint_spring(m, "j1", 20.0, 0.2));
  f.add(joint_damping(m, "j2", 0.3));
  f.add(joint_effort(m, "j3", cycloidal(2.0, 3.0)));
  f.add(std::make_shared<LuGreFriction>(m, "j4", LuGreParams{0.1, 0.2, 5.0, 0.02, 0.01, 0.1}));
  f.add(std::make_shared<FlexibleDrive>(m, "j5", FlexibleDriveParams{1e4, 70.0}, cycloidal(6.0, 5.0)));
  s->q.resize(5);
  s->q << 0.3, 0.4, 0.1, 0.5, 0.25;
  s->qd.resize(5);
  s->qd << 0.2, -0.1, 0.05, 0.3, -0.2;
  s->qdd.resize(5);
  s->qdd << 0.5, 0.2, -0.3, 0.1, 0.4;
  s->z = Eigen::VectorXd::Constant(1, 2e-3);
  s->zdot = Eigen::VectorXd::Constant(1, -0.01);
  return s;
}

Setup& paper_setup() {
  static auto s = paper();
  return *s;
}
Setup& kinds_setup() {
  static auto s = every_kind();
  return *s;
}

void constraints_double(benchmark::State& st, Setup& s) {
  Data data(s.model);
  ConstraintEval ev(s.model, s.constraints);
  for (auto _ : st) {
    evaluate_constraints(s.model, data, s.constraints, ev, s.t, s.q, s.qd);
    benchmark::DoNotOptimize(ev.gamma.data());
  }
}

void constraints_dual(benchmark::State& st, Setup& s) {
  ConstraintEvalDual ev(s.model, s.constraints);
  const int n = s.model.nv;
  std::vector<JacobianScalar> q(n), qd(n);
  for (int i = 0; i < n; ++i) {
    q[i] = JacobianScalar::variable(s.q[i], i % kJacobianDirections);
    qd[i] = JacobianScalar::variable(s.qd[i], (n + i) % kJacobianDirections);
  }
  for (auto _ : st) {
    evaluate_constraints_dual(s.model, s.constraints, ev, JacobianScalar(s.t), q.data(), qd.data());
    benchmark::DoNotOptimize(ev.gamma.data());
  }
}

void forces_double(benchmark::State& st, Setup& s, bool with_dQ) {
  const int n = s.model.nv;
  Eigen::VectorXd Q(n);
  Eigen::MatrixXd dQ(n, n);
  std::vector<double> zdot(std::max(1, s.forces.num_states()));
  for (auto _ : st) {
    s.forces.evaluate(s.t, s.q, s.qd, s.z.data(), Q, zdot.data(), with_dQ ? &dQ : nullptr);
    benchmark::DoNotOptimize(Q.data());
    benchmark::DoNotOptimize(dQ.data());
  }
}

void forces_dual(benchmark::State& st, Setup& s) {
  const int n = s.model.nv, nz = s.forces.num_states();
  std::vector<JacobianScalar> q(n), qd(n), z(std::max(1, nz)), Q(n), zdot(std::max(1, nz));
  for (int i = 0; i < n; ++i) {
    q[i] = JacobianScalar::variable(s.q[i], i % kJacobianDirections);
    qd[i] = JacobianScalar::variable(s.qd[i], (n + i) % kJacobianDirections);
  }
  for (int i = 0; i < nz; ++i) z[i] = JacobianScalar::variable(s.z[i], i % kJacobianDirections);
  for (auto _ : st) {
    s.forces.evaluate_dual(s.t, q.data(), qd.data(), z.data(), n, Q.data(), zdot.data());
    benchmark::DoNotOptimize(Q.data());
  }
}

void force_rates(benchmark::State& st, Setup& s) {
  Eigen::VectorXd Qdot = Eigen::VectorXd::Zero(s.model.nv);
  const auto& el = s.forces.elements();
  for (auto _ : st) {
    Qdot.setZero();
    for (size_t k = 0; k < el.size(); ++k) {
      const int off = s.forces.state_offset(static_cast<int>(k));
      el[k]->add_rate_with_states(s.t, s.q, s.qd, s.qdd, s.z.data() + off, s.zdot.data() + off, Qdot);
    }
    benchmark::DoNotOptimize(Qdot.data());
  }
}

void BM_Paper_Constraints(benchmark::State& st) { constraints_double(st, paper_setup()); }
void BM_Paper_ConstraintsDual(benchmark::State& st) { constraints_dual(st, paper_setup()); }
void BM_Paper_Forces(benchmark::State& st) { forces_double(st, paper_setup(), false); }
void BM_Paper_ForcesWithDQ(benchmark::State& st) { forces_double(st, paper_setup(), true); }
void BM_Paper_ForcesDual(benchmark::State& st) { forces_dual(st, paper_setup()); }
void BM_Paper_ForceRates(benchmark::State& st) { force_rates(st, paper_setup()); }
void BM_Kinds_Constraints(benchmark::State& st) { constraints_double(st, kinds_setup()); }
void BM_Kinds_ConstraintsDual(benchmark::State& st) { constraints_dual(st, kinds_setup()); }
void BM_Kinds_Forces(benchmark::State& st) { forces_double(st, kinds_setup(), false); }
void BM_Kinds_ForcesWithDQ(benchmark::State& st) { forces_double(st, kinds_setup(), true); }
void BM_Kinds_ForcesDual(benchmark::State& st) { forces_dual(st, kinds_setup()); }
void BM_Kinds_ForceRates(benchmark::State& st) { force_rates(st, kinds_setup()); }
BENCHMARK(BM_Paper_Constraints);
BENCHMARK(BM_Paper_ConstraintsDual);
BENCHMARK(BM_Paper_Forces);
BENCHMARK(BM_Paper_ForcesWithDQ);
BENCHMARK(BM_Paper_ForcesDual);
BENCHMARK(BM_Paper_ForceRates);
BENCHMARK(BM_Kinds_Constraints);
BENCHMARK(BM_Kinds_ConstraintsDual);
BENCHMARK(BM_Kinds_Forces);
BENCHMARK(BM_Kinds_ForcesWithDQ);
BENCHMARK(BM_Kinds_ForcesDual);
BENCHMARK(BM_Kinds_ForceRates);

}  // namespace

BENCHMARK_MAIN();
