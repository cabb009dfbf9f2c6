// Side-by-side timing of refdyn's recursive route, refdyn's trace route and Orocos KDL on the
// same models: the paper manipulator and random 7-, 15-, 30- and 60-DOF chains built from the
// same seeded standard-DH tables on both sides (dh_tables.hpp). See bench/README.md.
//
// Before timing, every model is checked once: M, g, c + g and τ from refdyn's recursive route,
// refdyn's trace route and KDL must agree to 1e-10 (relative to the largest entry); the
// program aborts loudly otherwise. At the end it prints the table of ratios KDL / refdyn.

#include "bench_report.hpp"
#include "dh_tables.hpp"
#include "kdl_peer.hpp"

#include "refdyn/model.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/recursive_dynamics.hpp"
#include "refdyn/trace_dynamics.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

using refdyn_bench::DHTable;
using refdyn_bench::KdlPeer;

constexpr int kStates = 8;  // states cycled through by every timed loop (same for all sides)

refdyn::Model model_from_table(const DHTable& t) {
  std::vector<refdyn::DHRow> rows;
  for (const auto& l : t.links) {
    refdyn::DHRow r;
    r.type = l.prismatic ? refdyn::JointType::Prismatic : refdyn::JointType::Revolute;
    r.theta = l.theta;
    r.d = l.d;
    r.a = l.a;
    r.alpha = l.alpha;
    r.inertia.mass = l.mass;
    r.inertia.com = refdyn::Vec3(l.com[0], l.com[1], l.com[2]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r.inertia.I_com(i, j) = l.I_com[3 * i + j];
    rows.push_back(r);
  }
  refdyn::ModelDescription d = refdyn::from_dh(rows, refdyn::DHConvention::Standard, t.name);
  d.gravity = refdyn::Vec3(t.gravity[0], t.gravity[1], t.gravity[2]);
  return refdyn::build_model(d);
}

struct Case {
  explicit Case(refdyn::Model m) : model(std::move(m)) {}
  std::string name;
  refdyn::Model model;
  std::unique_ptr<refdyn::Data> data;
  std::unique_ptr<KdlPeer> kdl;
  std::vector<Eigen::VectorXd> q, qd, qdd;
};

std::unique_ptr<Case> make_case(const DHTable& table, refdyn::Model model, std::uint32_t seed) {
  auto c = std::make_unique<Case>(std::move(model));
  c->name = table.name;
  c->data = std::make_unique<refdyn::Data>(c->model);
  c->kdl = std::make_unique<KdlPeer>(table);
  const int n = c->model.nq;
  if (c->kdl->dof() != n) {
    std::fprintf(stderr, "FATAL: %s: KDL chain has %d joints, refdyn model %d\n", c->name.c_str(),
                 c->kdl->dof(), n);
    std::exit(2);
  }
  const auto q = refdyn_bench::random_states(n, kStates, 3.0, seed);
  const auto qd = refdyn_bench::random_states(n, kStates, 2.0, seed + 1);
  const auto qdd = refdyn_bench::random_states(n, kStates, 5.0, seed + 2);
  c->kdl->load_states(q.data(), qd.data(), qdd.data(), kStates);
  for (int k = 0; k < kStates; ++k) {
    c->q.push_back(Eigen::Map<const Eigen::VectorXd>(q.data() + k * n, n));
    c->qd.push_back(Eigen::Map<const Eigen::VectorXd>(qd.data() + k * n, n));
    c->qdd.push_back(Eigen::Map<const Eigen::VectorXd>(qdd.data() + k * n, n));
  }
  return c;
}

// ---------------------------------------------------------------------------------------------
// Start-up agreement check.

double rel_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const double scale = std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), 1e-300});
  return (a - b).cwiseAbs().maxCoeff() / scale;
}

bool check_case(Case& c, double tol) {
  const int n = c.model.nq;
  refdyn::Data& data = *c.data;
  bool ok = true;
  double worst = 0;
  auto expect = [&](const char* what, int k, const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    const double d = rel_diff(a, b);
    worst = std::max(worst, d);
    if (!(d <= tol)) {
      ok = false;
      std::fprintf(stderr, "FATAL: %s state %d: %s differ, relative max difference %.3e > %.0e\n",
                   c.name.c_str(), k, what, d, tol);
    }
  };
  Eigen::MatrixXd Mk(n, n);
  Eigen::VectorXd ck(n), gk(n), tk(n);
  for (int k = 0; k < kStates; ++k) {
    if (c.kdl->mass_matrix(k) != 0 || c.kdl->coriolis(k) != 0 || c.kdl->gravity(k) != 0 ||
        c.kdl->inverse_dynamics(k) != 0) {
      std::fprintf(stderr, "FATAL: %s: a KDL solver returned an error\n", c.name.c_str());
      return false;
    }
    c.kdl->get_mass_matrix(Mk.data());
    c.kdl->get_coriolis(ck.data());
    c.kdl->get_gravity(gk.data());
    c.kdl->get_tau(tk.data());
    const Eigen::MatrixXd M = refdyn::mass_matrix(c.model, data, c.q[k]);
    expect("M: refdyn recursive vs KDL JntToMass", k, M, Mk);
    expect("M: refdyn recursive vs refdyn trace", k, M, refdyn::trace_mass_matrix(c.model, data, c.q[k]));
    const Eigen::VectorXd g = refdyn::gravity_forces(c.model, data, c.q[k]);
    expect("g: refdyn recursive vs KDL JntToGravity", k, g, gk);
    const Eigen::VectorXd cg = refdyn::bias_forces(c.model, data, c.q[k], c.qd[k]);
    expect("c+g: refdyn recursive vs KDL JntToCoriolis+JntToGravity", k, cg, ck + gk);
    const Eigen::VectorXd cg_trace = refdyn::trace_coriolis(c.model, data, c.q[k], c.qd[k]) +
                                     refdyn::trace_gravity(c.model, data, c.q[k]);
    expect("c+g: refdyn recursive vs refdyn trace", k, cg, cg_trace);
    const Eigen::VectorXd tau = refdyn::inverse_dynamics(c.model, data, c.q[k], c.qd[k], c.qdd[k]);
    expect("tau: refdyn RNEA vs KDL ChainIdSolver_RNE", k, tau, tk);
    expect("tau: refdyn RNEA vs M qdd + c + g", k, tau, M * c.qdd[k] + cg);
  }
  std::printf("check %-8s %2d DOF: recursive, trace and KDL agree (worst relative difference %.1e)\n",
              c.name.c_str(), n, worst);
  return ok;
}

// ---------------------------------------------------------------------------------------------
// Timed loops.

template <typename F>
void timed(benchmark::State& st, F&& f) {
  unsigned k = 0;
  for (auto _ : st) {
    f(static_cast<int>(k++ % kStates));
    benchmark::ClobberMemory();
  }
}

const std::vector<std::string> kQuantities = {"M", "c+g", "g", "ID"};
const std::vector<std::string> kRoutes = {"recursive", "trace", "kdl"};

void register_case(Case* c) {
  const std::string p = c->name + "/";
  refdyn::Data* d = c->data.get();
  const refdyn::Model* m = &c->model;
  KdlPeer* kdl = c->kdl.get();
  auto reg = [](const std::string& name, auto fn) {
    benchmark::RegisterBenchmark(name.c_str(), [fn](benchmark::State& st) { timed(st, fn); })
        ->Unit(benchmark::kNanosecond)
        ->ComputeStatistics("min", [](const std::vector<double>& v) {
          return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
        });
  };
  // Joint-space mass matrix.
  reg(p + "M/recursive", [=](int k) { benchmark::DoNotOptimize(refdyn::mass_matrix(*m, *d, c->q[k]).data()); });
  reg(p + "M/trace", [=](int k) { benchmark::DoNotOptimize(refdyn::trace_mass_matrix(*m, *d, c->q[k]).data()); });
  reg(p + "M/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->mass_matrix(k)); });
  // Bias forces c + g.
  reg(p + "c+g/recursive", [=](int k) {
    benchmark::DoNotOptimize(refdyn::bias_forces(*m, *d, c->q[k], c->qd[k]).data());
  });
  reg(p + "c+g/trace", [=](int k) {
    benchmark::DoNotOptimize(refdyn::trace_coriolis(*m, *d, c->q[k], c->qd[k]).data());
    benchmark::DoNotOptimize(refdyn::trace_gravity(*m, *d, c->q[k]).data());
  });
  reg(p + "c+g/kdl", [=](int k) {
    benchmark::DoNotOptimize(kdl->coriolis(k));
    benchmark::DoNotOptimize(kdl->gravity(k));
  });
  // Gravity alone.
  reg(p + "g/recursive", [=](int k) { benchmark::DoNotOptimize(refdyn::gravity_forces(*m, *d, c->q[k]).data()); });
  reg(p + "g/trace", [=](int k) { benchmark::DoNotOptimize(refdyn::trace_gravity(*m, *d, c->q[k]).data()); });
  reg(p + "g/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->gravity(k)); });
  // Inverse dynamics (no trace-route counterpart).
  reg(p + "ID/recursive", [=](int k) {
    benchmark::DoNotOptimize(refdyn::inverse_dynamics(*m, *d, c->q[k], c->qd[k], c->qdd[k]).data());
  });
  reg(p + "ID/kdl", [=](int k) { benchmark::DoNotOptimize(kdl->inverse_dynamics(k)); });
}

// ---------------------------------------------------------------------------------------------
// Reporting: the console shows the median and min aggregates; every repetition is collected
// for the final ratio table.

using refdyn_bench::fmt_ns;
using refdyn_bench::fmt_ratio;
using refdyn_bench::Reporter;
using refdyn_bench::Stats;

void print_ratio_table(const std::vector<std::unique_ptr<Case>>& cases, const Reporter& rep) {
  auto get = [&](const std::string& key) -> const Stats* {
    auto it = rep.stats.find(key);
    return it == rep.stats.end() ? nullptr : &it->second;
  };
  std::printf("\nRatios KDL / refdyn recursive and trace / recursive (> 1: refdyn's recursive route is faster).\n");
  std::printf("Times are CPU time per call; 'med' = median over repetitions, 'min' = fastest repetition;\n");
  std::printf("ratios are med/med and min/min.\n\n");
  std::printf("| model | DOF | quantity | recursive med | recursive min | KDL med | KDL min | KDL/rec med | KDL/rec min | trace med | trace/rec med |\n");
  std::printf("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& c : cases)
    for (const auto& qty : kQuantities) {
      const std::string p = c->name + "/" + qty + "/";
      const Stats* r = get(p + "recursive");
      const Stats* k = get(p + "kdl");
      const Stats* t = get(p + "trace");
      if (!r && !k && !t) continue;
      const double rm = r ? r->median() : NAN, rn = r ? r->min() : NAN;
      const double km = k ? k->median() : NAN, kn = k ? k->min() : NAN;
      const double tm = t ? t->median() : NAN;
      std::printf("| %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", c->name.c_str(), c->model.nq,
                  qty.c_str(), fmt_ns(rm).c_str(), fmt_ns(rn).c_str(), fmt_ns(km).c_str(), fmt_ns(kn).c_str(),
                  fmt_ratio(km / rm).c_str(), fmt_ratio(kn / rn).c_str(), fmt_ns(tm).c_str(),
                  fmt_ratio(tm / rm).c_str());
    }
  std::printf("\nM = mass matrix (refdyn mass_matrix [CRBA] | trace_mass_matrix | KDL ChainDynParam::JntToMass)\n");
  std::printf("c+g = bias forces (bias_forces [RNEA, qdd = 0] | trace_coriolis + trace_gravity |\n");
  std::printf("      JntToCoriolis + JntToGravity)\n");
  std::printf("g = gravity (gravity_forces | trace_gravity | JntToGravity)\n");
  std::printf("ID = inverse dynamics (inverse_dynamics [RNEA] | - | ChainIdSolver_RNE::CartToJnt)\n");
}

}  // namespace

int main(int argc, char** argv) {
  // Defaults (overridable on the command line, later flags win): interleaved repetitions.
  if (!refdyn_bench::initialize_with_defaults(argc, argv)) return 1;

  std::vector<std::unique_ptr<Case>> cases;
  cases.push_back(make_case(refdyn_bench::paper_table(), refdyn::models::paper_manipulator(), 101));
  for (int dof : {7, 15, 30, 60}) {
    const DHTable t = refdyn_bench::random_table(dof, 1000 + dof);
    cases.push_back(make_case(t, model_from_table(t), 2000 + dof));
  }

  bool ok = true;
  for (auto& c : cases) ok = check_case(*c, 1e-10) && ok;
  if (!ok) {
    std::fprintf(stderr, "FATAL: refdyn and KDL disagree: the timings would not compare the same quantities. "
                         "Aborting.\n");
    std::abort();
  }
  std::printf("\n");
  std::fflush(stdout);

  for (auto& c : cases) register_case(c.get());
  Reporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  print_ratio_table(cases, reporter);
  benchmark::Shutdown();
  return 0;
}
