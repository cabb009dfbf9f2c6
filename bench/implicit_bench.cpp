// The cost of the exact Jacobian ∂f/∂x of the reference dynamics (implicit integration,
// docs/implicit.md) against one evaluation of f, at 3 DOF (the paper's arm with stiff LuGre in
// every joint and its two programmed constraints: n_x = 2·3 + 3 = 9) and 7 DOF (a random
// 7-link DH arm with LuGre in every joint and a tip on a sphere and at a height: n_x = 21).
// The target: a Jacobian costs at most ~(2n + n_z + 2) evaluations of f (11 and 23).
//   implicit_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include "dh_models.hpp"
#include "dh_tables.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <benchmark/benchmark.h>

#include <memory>

using namespace refdyn;

namespace {

struct Setup {
  explicit Setup(Model m) : model(std::move(m)) {}
  Model model;
  ForceSet forces;
  ConstraintSet constraints;
  std::unique_ptr<ReferenceDynamics> rd;
  Eigen::VectorXd x;
};

std::unique_ptr<Setup> paper() {
  models::PaperExampleParams p;
  p.lugre_rot.sigma0 = p.lugre_lin.sigma0 = 1e5;
  p.lugre_rot.sigma1 = p.lugre_lin.sigma1 = 300;
  static models::PaperExample ex(p);  // owns what the dynamics refers to
  auto s = std::make_unique<Setup>(ex.model);
  s->rd = std::make_unique<ReferenceDynamics>(ex.model, ex.forces, ex.constraints, ex.options());
  s->x = s->rd->make_state(ex.q0(), Eigen::Vector3d(0.1, -0.2, 0.05));
  s->x.tail(3) << 1e-7, -2e-7, 1e-8;
  return s;
}

std::unique_ptr<Setup> arm7() {
  ModelDescription d = refdyn_bench::description_from_table(refdyn_bench::random_table(7, 7));
  d.add_point("tip", d.links.back().name, Vec3(0.05, 0.02, 0.1));
  auto s = std::make_unique<Setup>(build_model(d));
  for (int j = 0; j < 7; ++j)
    s->forces.add(std::make_shared<LuGreFriction>(s->model, s->model.joint_name[j], LuGreParams{0.3, 0.2, 1e5, 300, 0, 0.1}));
  Eigen::VectorXd q(7), qd(7);
  q << 0.3, -0.5, 0.2, 0.9, -0.4, 0.6, 0.1;
  qd << 0.1, -0.2, 0.3, 0.05, -0.1, 0.2, 0.15;
  // Constraints through the tip where it is now: on a sphere about the base, at its height.
  Data data(s->model);
  forward_kinematics(s->model, data, q);
  const Vec3 r = point_position(s->model, data, s->model.point_index("tip"));
  s->constraints.add(point_on_surface(s->model, "tip", sphere(Vec3::Zero(), r.norm())));
  s->constraints.add(point_coordinate(s->model, "tip", 2, constant(r.z())));
  s->rd = std::make_unique<ReferenceDynamics>(s->model, s->forces, s->constraints);
  s->x = s->rd->make_state(q, qd);
  return s;
}

void derivative(benchmark::State& state, Setup& s) {
  Eigen::VectorXd xdot(s.x.size());
  for (auto _ : state) {
    s.rd->derivative(0.5, s.x, xdot);
    benchmark::DoNotOptimize(xdot.data());
  }
}
void jacobian(benchmark::State& state, Setup& s) {
  Eigen::MatrixXd J;
  for (auto _ : state) {
    s.rd->jacobian(0.5, s.x, J);
    benchmark::DoNotOptimize(J.data());
  }
  state.counters["n_x"] = static_cast<double>(s.x.size());
}

void BM_Paper3_Derivative(benchmark::State& st) { static auto s = paper(); derivative(st, *s); }
void BM_Paper3_Jacobian(benchmark::State& st) { static auto s = paper(); jacobian(st, *s); }
void BM_Arm7_Derivative(benchmark::State& st) { static auto s = arm7(); derivative(st, *s); }
void BM_Arm7_Jacobian(benchmark::State& st) { static auto s = arm7(); jacobian(st, *s); }
BENCHMARK(BM_Paper3_Derivative);
BENCHMARK(BM_Paper3_Jacobian);
BENCHMARK(BM_Arm7_Derivative);
BENCHMARK(BM_Arm7_Jacobian);

}  // namespace

BENCHMARK_MAIN();
