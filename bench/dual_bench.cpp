// Forward-mode derivatives through the generic multibody core (refdyn/multibody/): the home-made
// fixed-size refdyn::multibody::Dual<N> against Eigen's AutoDiffScalar (unsupported/Eigen/AutoDiff,
// Debian libeigen3-dev) with heap (VectorXd), fixed-capacity and fixed-size derivative vectors,
// and against central differences — for (a) one time derivative along the motion (the jerk
// route), (b) the Jacobian ∂τ/∂(q, q̇) of the inverse dynamics (2n directions, the shape of the
// ∂f/∂x an implicit integrator needs). Random standard-DH chains of 7 and 30 DOF. README
// "Dual numbers" quotes the run.
#include "dh_models.hpp"
#include "dh_tables.hpp"

#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <unsupported/Eigen/AutoDiff>

#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

namespace ad_detail {
template <class A> A ad_sin(const A& x) { using std::sin; return A(sin(x)); }
template <class A> A ad_cos(const A& x) { using std::cos; return A(cos(x)); }
template <class A> A ad_sqrt(const A& x) { using std::sqrt; return A(sqrt(x)); }
}  // namespace ad_detail

namespace refdyn::multibody {
template <class Der>
struct ScalarTraits<Eigen::AutoDiffScalar<Der>> {
  using A = Eigen::AutoDiffScalar<Der>;
  static A from_double(double v) { return A(v); }
  static A sin(const A& x) { return ad_detail::ad_sin(x); }
  static A cos(const A& x) { return ad_detail::ad_cos(x); }
  static A sqrt(const A& x) { return ad_detail::ad_sqrt(x); }
  static bool is_zero(const A& x) { return x.value() == 0 && x.derivatives().isZero(0); }
};
}  // namespace refdyn::multibody

namespace {

namespace mb = refdyn::multibody;

refdyn::Model chain(int dof) {
  return refdyn::build_model(refdyn_bench::description_from_table(refdyn_bench::random_table(dof, 4000 + dof)));
}

struct State {
  refdyn::Model model;
  Eigen::VectorXd q, qd, qdd;
  explicit State(int n) : model(chain(n)) {
    const std::vector<double> s = refdyn_bench::random_states(n, 3, 1.0, 77);
    q = Eigen::Map<const Eigen::VectorXd>(s.data(), n);
    qd = Eigen::Map<const Eigen::VectorXd>(s.data() + n, n);
    qdd = Eigen::Map<const Eigen::VectorXd>(s.data() + 2 * n, n);
  }
};

/// The workspace of one evaluation over S (reused: no allocation inside the timed loops).
template <class S>
struct Work {
  std::vector<S> q, qd, qdd, tau;
  mb::Poses<S> poses;
  mb::NewtonEulerWork<S> ne;
};

/// τ over S with q, q̇ seeded by `seed(i, k, value)`: k = 0 q_i, k = 1 q̇_i.
template <class S, class Seed>
const std::vector<S>& tau_of(const mb::Bodies<S>& B, const State& st, const Seed& seed) {
  thread_local Work<S> w;
  const int n = st.model.nv;
  w.q.resize(n);
  w.qd.resize(n);
  w.qdd.resize(n);
  for (int i = 0; i < n; ++i) {
    w.q[i] = seed(i, 0, st.q[i]);
    w.qd[i] = seed(i, 1, st.qd[i]);
    w.qdd[i] = mb::from_double<S>(st.qdd[i]);
  }
  mb::forward_poses(B, w.q, w.poses);
  mb::inverse_dynamics(B, w.poses, st.model.gravity, w.qd.data(), w.qdd.data(), true, w.ne, w.tau);
  return w.tau;
}

void BM_rnea_fast(benchmark::State& bs) {
  const State st(static_cast<int>(bs.range(0)));
  refdyn::Data data(st.model);
  Eigen::VectorXd tau(st.model.nv);
  for (auto _ : bs) {
    refdyn::unchecked::rnea(st.model, data, st.q, &st.qd, &st.qdd, true, tau);
    benchmark::DoNotOptimize(tau.data());
  }
}

void BM_rnea_generic_double(benchmark::State& bs) {
  const State st(static_cast<int>(bs.range(0)));
  const mb::Bodies<double> B = mb::bodies_from_model<double>(st.model);
  for (auto _ : bs) benchmark::DoNotOptimize(tau_of(B, st, [](int, int, double v) { return v; }));
}

/// (b) ∂τ/∂(q, q̇) by central differences of the fast kernel: 4n RNEAs.
void BM_jacobian_central_fd(benchmark::State& bs) {
  const State st(static_cast<int>(bs.range(0)));
  const int n = st.model.nv;
  refdyn::Data data(st.model);
  Eigen::VectorXd tp(n), tm(n);
  Eigen::MatrixXd J(n, 2 * n);
  for (auto _ : bs) {
    for (int c = 0; c < 2 * n; ++c) {
      Eigen::VectorXd q = st.q, qd = st.qd;
      double& x = c < n ? q[c] : qd[c - n];
      const double x0 = x, h = 1e-6 * std::max(1.0, std::abs(x0));
      x = x0 + h;
      refdyn::unchecked::rnea(st.model, data, q, &qd, &st.qdd, true, tp);
      x = x0 - h;
      refdyn::unchecked::rnea(st.model, data, q, &qd, &st.qdd, true, tm);
      J.col(c) = (tp - tm) / (2 * h);
    }
    benchmark::DoNotOptimize(J.data());
  }
}

/// (b) with Dual<N>: ⌈2n/N⌉ sweeps of N directions.
template <int N>
void BM_jacobian_dual(benchmark::State& bs) {
  using D = mb::Dual<N>;
  const State st(static_cast<int>(bs.range(0)));
  const int n = st.model.nv;
  const mb::Bodies<D> B = mb::bodies_from_model<D>(st.model);
  Eigen::MatrixXd J(n, 2 * n);
  for (auto _ : bs) {
    for (int c0 = 0; c0 < 2 * n; c0 += N) {
      const std::vector<D>& t = tau_of(B, st, [&](int i, int k, double v) {
        D d(v);
        const int col = k * n + i - c0;
        if (col >= 0 && col < N) d.d[col] = 1.0;
        return d;
      });
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < N && c0 + k < 2 * n; ++k) J(i, c0 + k) = t[i].d[k];
    }
    benchmark::DoNotOptimize(J.data());
  }
}

/// (b) with AutoDiffScalar<Der>: ⌈2n/chunk⌉ sweeps of `chunk` directions (chunk = 2n when the
/// derivative vector is dynamic).
template <class Der>
void BM_jacobian_autodiff(benchmark::State& bs) {
  using A = Eigen::AutoDiffScalar<Der>;
  const State st(static_cast<int>(bs.range(0)));
  const int n = st.model.nv;
  const int chunk = Der::SizeAtCompileTime == Eigen::Dynamic ? 2 * n : static_cast<int>(Der::SizeAtCompileTime);
  const mb::Bodies<A> B = mb::bodies_from_model<A>(st.model);
  Eigen::MatrixXd J(n, 2 * n);
  for (auto _ : bs) {
    for (int c0 = 0; c0 < 2 * n; c0 += chunk) {
      const std::vector<A>& t = tau_of(B, st, [&](int i, int k, double v) {
        A d(v, Der::Zero(chunk));
        const int col = k * n + i - c0;
        if (col >= 0 && col < chunk) d.derivatives()[col] = 1.0;
        return d;
      });
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < chunk && c0 + k < 2 * n; ++k) J(i, c0 + k) = t[i].derivatives()[k];
    }
    benchmark::DoNotOptimize(J.data());
  }
}

/// (a) one time derivative along (q̇, q̈): Dual<1> against AutoDiffScalar<Matrix<double, 1, 1>>.
void BM_rate_dual1(benchmark::State& bs) {
  using D = mb::Dual<1>;
  const State st(static_cast<int>(bs.range(0)));
  const mb::Bodies<D> B = mb::bodies_from_model<D>(st.model);
  for (auto _ : bs)
    benchmark::DoNotOptimize(tau_of(B, st, [&](int i, int k, double v) {
      return D::variable(v, 0, k == 0 ? st.qd[i] : st.qdd[i]);
    }));
}
void BM_rate_autodiff1(benchmark::State& bs) {
  using Der = Eigen::Matrix<double, 1, 1>;
  using A = Eigen::AutoDiffScalar<Der>;
  const State st(static_cast<int>(bs.range(0)));
  const mb::Bodies<A> B = mb::bodies_from_model<A>(st.model);
  for (auto _ : bs)
    benchmark::DoNotOptimize(tau_of(B, st, [&](int i, int k, double v) {
      return A(v, Der::Constant(k == 0 ? st.qd[i] : st.qdd[i]));
    }));
}

using Fixed8 = Eigen::Matrix<double, 8, 1>;
using Cap64 = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 64, 1>;

}  // namespace

#define SIZES ->Arg(7)->Arg(30)->Unit(benchmark::kMicrosecond)
BENCHMARK(BM_rnea_fast) SIZES;
BENCHMARK(BM_rnea_generic_double) SIZES;
BENCHMARK(BM_rate_dual1) SIZES;
BENCHMARK(BM_rate_autodiff1) SIZES;
BENCHMARK(BM_jacobian_central_fd) SIZES;
BENCHMARK(BM_jacobian_dual<1>) SIZES;
BENCHMARK(BM_jacobian_dual<8>) SIZES;
BENCHMARK(BM_jacobian_dual<16>) SIZES;
BENCHMARK(BM_jacobian_autodiff<Fixed8>) SIZES;
BENCHMARK(BM_jacobian_autodiff<Cap64>) SIZES;
BENCHMARK(BM_jacobian_autodiff<Eigen::VectorXd>) SIZES;
BENCHMARK_MAIN();
