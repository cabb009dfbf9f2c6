// The phase-plane (TOPP-RA) method of refdyn optimize (optimize/phase_plane.hpp).
#include "refdyn/optimize/phase_plane.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace refdyn {

PathDynamics path_dynamics(const Model& model, const Plan& plan) {
  PathDynamics p;
  Data data(model);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nq);
  const size_t n = plan.t.size();
  if (n < 2 || plan.x.size() != n || plan.qdd.size() != n || plan.actuator_effort.size() != n)
    throw Error("the phase-plane method needs the task's plan with accelerations and efforts at every sample");
  for (size_t k = 0; k < n; ++k) {
    const int n = model.nq;
    const Eigen::VectorXd q = plan.x[k].head(n), dq = plan.x[k].segment(n, n);
    const Eigen::VectorXd& ddq = plan.qdd[k];
    if (!q.allFinite() || !dq.allFinite() || !ddq.allFinite())
      throw Error("the task's plan (without its time law) is not finite at t = " + fmt(plan.t[k]));
    const Eigen::VectorXd c = gravity_forces(model, data, q);
    const Eigen::VectorXd a = inverse_dynamics(model, data, q, zero, dq) - c;   // M q'
    const Eigen::VectorXd b = inverse_dynamics(model, data, q, dq, ddq) - c;   // M q'' + c(q, q')
    // In task time (ṡ = 1, s̈ = 0) the plan's effort is b + c: the check that the effort has the
    // phase-plane form (no force elements, no reactions of material constraints in it).
    const Eigen::VectorXd& eff = plan.actuator_effort[k];
    for (int j = 0; j < model.nq; ++j) {
      const double d = std::abs(eff[j] - b[j] - c[j]);
      p.worst_effort_mismatch = std::max(p.worst_effort_mismatch, d);
      if (!(d <= 1e-6 * (1 + std::abs(eff[j]))))
        throw Error("the phase-plane method needs the actuator effort to be the rigid-body inverse dynamics along "
                    "the path, but at t = " + fmt(plan.t[k]) + " the effort of " + model.joint_name[static_cast<size_t>(j)] +
                    " is " + fmt(eff[j]) + " and M q'' + c + g is " + fmt(b[j] + c[j]) +
                    " (force elements or material constraints take part; hint: method: cobyla or slsqp)");
    }
    p.tau.push_back(plan.t[k]);
    p.a.push_back(a);
    p.b.push_back(b);
    p.c.push_back(c);
    p.dq.push_back(dq);
  }
  return p;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// α x_i + β x_{i+1} ≤ γ
struct Row {
  double alpha, beta, gamma;
};

/// The rows of part i (task time [τ_i, τ_i + Δ]) from every path sample inside it.
std::vector<Row> part_rows(const PathDynamics& p, double t0, double delta, const PhasePlaneLimits& L) {
  std::vector<Row> rows;
  const double t1 = t0 + delta, eps = 1e-9 * delta;
  const size_t k0 = static_cast<size_t>(std::lower_bound(p.tau.begin(), p.tau.end(), t0 - eps) - p.tau.begin());
  for (size_t k = k0; k < p.tau.size() && p.tau[k] <= t1 + eps; ++k) {
    const double l = std::clamp((p.tau[k] - t0) / delta, 0.0, 1.0);
    for (int j = 0; j < p.a[k].size(); ++j) {
      // effort = a (x_{i+1} − x_i)/(2Δ) + b ((1 − l) x_i + l x_{i+1}) + c
      const double a = p.a[k][j], b = p.b[k][j], c = p.c[k][j];
      const double al = -a / (2 * delta) + b * (1 - l), be = a / (2 * delta) + b * l;
      if (std::isfinite(L.effort[j])) {
        rows.push_back({al, be, L.effort[j] - c});
        rows.push_back({-al, -be, L.effort[j] + c});
      }
    }
  }
  // A row with both coefficients positive (an effort row where a = M q' nearly vanishes) is
  // replaced by the two bounds x_i, x_{i+1} ≤ γ/(α + β), which imply
  // it (x is their convex combination): then every row bounds x_{i+1} by an increasing function
  // of x_i or the reverse, the admissible sequences are closed under the componentwise maximum,
  // and the greedy forward pass is the time optimum (Pham & Pham 2018). Without this a greedy
  // step to the largest x_i can force x_{i+1} to nearly 0 (speed rows kept this way: +18 % on
  // the 2R circle with speed limits; they are knot bounds instead, speed_bounds).
  std::vector<Row> out;
  out.reserve(rows.size());
  for (const Row& r : rows) {
    const double tiny = 1e-14 * (std::abs(r.alpha) + std::abs(r.beta));
    if (r.alpha > tiny && r.beta > tiny) {
      out.push_back({r.alpha + r.beta, 0.0, r.gamma});
      out.push_back({0.0, r.alpha + r.beta, r.gamma});
    } else {
      out.push_back(r);
    }
  }
  return out;
}

/// The speed limits as bounds on the knots' x: x(τ) = ṡ² must stay under the maximum velocity
/// curve X(τ) = min_j v_j²/q'_j(τ)² at every path sample, and x is linear on each part. Bounds
/// B_i start at X at the knot (its nearest sample) and the two ends of every part whose chord
/// rises above X somewhere are lowered by the worst ratio, until no chord does: pure bounds
/// (the componentwise maximum of admissible sequences stays admissible), within O(Δ²) of X where
/// X is smooth (splitting each sample's row into bounds on both knots loses O(Δ): measured +2.7 %
/// at 32 parts on the 2R circle).
std::vector<double> speed_bounds(const PathDynamics& p, double T0, double delta, int K, const PhasePlaneLimits& L) {
  const size_t Ks = static_cast<size_t>(K);
  std::vector<double> X(p.tau.size(), kInf);
  for (size_t k = 0; k < p.tau.size(); ++k)
    for (int j = 0; j < p.dq[k].size(); ++j)
      if (std::isfinite(L.speed[j])) {
        const double d2 = p.dq[k][j] * p.dq[k][j];
        if (d2 > 0) X[k] = std::min(X[k], L.speed[j] * L.speed[j] / d2);
      }
  std::vector<double> B(Ks + 1, kInf);
  for (size_t i = 0; i <= Ks; ++i) {  // X at the sample nearest to the knot
    const double at = T0 + static_cast<double>(i) * delta;
    const auto it = std::lower_bound(p.tau.begin(), p.tau.end(), at);
    size_t k = static_cast<size_t>(it - p.tau.begin());
    if (k == p.tau.size() || (k > 0 && at - p.tau[k - 1] < p.tau[k] - at)) k = k ? k - 1 : 0;
    B[i] = X[k];
  }
  const double eps = 1e-9 * delta;
  for (int sweep = 0; sweep < 1000; ++sweep) {
    bool lowered = false;
    for (size_t i = 0; i < Ks; ++i) {
      const double t0 = T0 + static_cast<double>(i) * delta;
      double r = 1;
      const size_t k0 = static_cast<size_t>(std::lower_bound(p.tau.begin(), p.tau.end(), t0 - eps) - p.tau.begin());
      for (size_t k = k0; k < p.tau.size() && p.tau[k] <= t0 + delta + eps; ++k) {
        if (!std::isfinite(X[k])) continue;
        const double l = std::clamp((p.tau[k] - t0) / delta, 0.0, 1.0);
        const double chord = std::isfinite(B[i]) && std::isfinite(B[i + 1]) ? (1 - l) * B[i] + l * B[i + 1]
                                                                             : kInf;
        if (!std::isfinite(chord)) {  // a knot without a bound (speed never limited there): bound it now
          if (!std::isfinite(B[i])) B[i] = X[k];
          if (!std::isfinite(B[i + 1])) B[i + 1] = X[k];
          lowered = true;
          continue;
        }
        if (chord > X[k]) r = std::min(r, X[k] / chord);
      }
      if (r < 1) {
        B[i] *= r * (1 - 1e-12);
        B[i + 1] *= r * (1 - 1e-12);
        lowered = true;
      }
    }
    if (!lowered) break;
  }
  return B;
}

/// For a given x_i: the interval [lo, hi] of admissible x_{i+1} (lo > hi: none), with
/// x_{i+1} ∈ [next_lo, next_hi]; rows without x_{i+1} bound x_i itself (infeasible: lo = +inf).
void next_interval(const std::vector<Row>& rows, double x, double next_lo, double next_hi, double& lo, double& hi) {
  lo = next_lo;
  hi = next_hi;
  for (const Row& r : rows) {
    const double rest = r.gamma - r.alpha * x;
    if (std::abs(r.beta) <= 1e-14 * (std::abs(r.alpha) + 1)) {
      if (rest < -1e-12 * (std::abs(r.gamma) + 1)) {
        lo = kInf;
        return;
      }
    } else if (r.beta > 0) {
      hi = std::min(hi, rest / r.beta);
    } else {
      lo = std::max(lo, rest / r.beta);
    }
  }
}

/// Width of the admissible interval of x_{i+1} (concave in x_i: a minimum of affine functions
/// minus a maximum of affine functions); −inf where a row without x_{i+1} is violated.
double width(const std::vector<Row>& rows, double x, double next_lo, double next_hi) {
  double lo, hi;
  next_interval(rows, x, next_lo, next_hi, lo, hi);
  return std::isinf(lo) && lo > 0 ? -kInf : hi - lo;
}

}  // namespace

std::vector<double> phase_plane_knot_law(const PathDynamics& path, int K, const PhasePlaneLimits& limits,
                                         const std::vector<double>& lower, const std::vector<double>& upper) {
  if (K < 2) throw Error("the phase-plane method needs at least 2 parts");
  if (path.tau.size() < 2) throw Error("the phase-plane method needs a path with samples");
  const double T0 = path.tau.front(), Tp = path.tau.back() - T0, delta = Tp / K;
  const size_t Ks = static_cast<size_t>(K);
  std::vector<double> kmin(Ks + 1, 0.0), kmax(Ks + 1, 0.0);
  std::vector<std::vector<Row>> rows(Ks);
  for (int i = 0; i < K; ++i) rows[static_cast<size_t>(i)] = part_rows(path, T0 + i * delta, delta, limits);
  const std::vector<double> vb = speed_bounds(path, T0, delta, K, limits);
  // Backward: the controllable interval of every knot (x_K = 0).
  for (int i = K - 1; i >= 0; --i) {
    const size_t u = static_cast<size_t>(i);
    const std::vector<Row>& r = rows[u];
    double a = i == 0 ? 0.0 : lower[u], b = i == 0 ? 0.0 : std::min(upper[u], vb[u]);
    if (!(a <= b)) throw Error("knot " + std::to_string(i) + ": lower bound above the upper bound");
    auto f = [&](double x) { return width(r, x, kmin[u + 1], kmax[u + 1]); };
    // The maximum of the concave width by golden-section search, then the ends of {width ≥ 0}.
    double lo = a, hi = b;
    const double g = (std::sqrt(5.0) - 1) / 2;
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
    for (int it = 0; it < 200 && hi - lo > 1e-15 * (1 + hi); ++it) {
      if (f1 < f2) {
        lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
      } else {
        hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
      }
    }
    double xm = f1 >= f2 ? x1 : x2;
    for (double e : {a, b})
      if (f(e) > f(xm)) xm = e;
    if (!(f(xm) >= -1e-12 * (1 + std::abs(xm))))
      throw Error("no admissible time law on these knots: from knot " + std::to_string(i) + " (task time " +
                  fmt(T0 + i * delta) + " s) the task cannot reach its end at rest within the limits" +
                  (i == 0 ? " (it cannot even start from rest: check the effort limits against gravity)" : ""));
    auto edge = [&](double in, double out) {  // f(in) ≥ 0; the last point toward `out` with f ≥ 0
      if (f(out) >= 0) return out;
      for (int it = 0; it < 200 && std::abs(out - in) > 1e-15 * (1 + std::abs(in)); ++it) {
        const double mid = 0.5 * (in + out);
        (f(mid) >= 0 ? in : out) = mid;
      }
      return in;
    };
    kmax[u] = edge(xm, b);
    kmin[u] = edge(xm, a);
  }
  // Forward: the largest admissible x at each knot (x_0 = 0).
  std::vector<double> x(Ks + 1, 0.0);
  for (size_t i = 0; i < Ks; ++i) {
    double lo, hi;
    next_interval(rows[i], x[i], kmin[i + 1], kmax[i + 1], lo, hi);
    x[i + 1] = std::max(std::min(hi, kmax[i + 1]), kmin[i + 1]);
    if (i + 1 < Ks && !(x[i + 1] > 0))
      throw Error("no admissible time law on these knots: the task stops at knot " + std::to_string(i + 1) +
                  " (task time " + fmt(T0 + static_cast<double>(i + 1) * delta) + " s) within the limits");
  }
  x[Ks] = 0.0;
  return x;
}

double phase_plane_time_optimum(const PathDynamics& path, const PhasePlaneLimits& limits, double max_x) {
  const int fine = static_cast<int>(path.tau.size()) - 1, half = fine / 2;
  if (half < 2) return std::numeric_limits<double>::quiet_NaN();
  const double task = path.tau.back() - path.tau.front();
  auto fastest = [&](int K) {
    const std::vector<double> lower(static_cast<size_t>(K) + 1, 0.0), upper(static_cast<size_t>(K) + 1, max_x);
    return knot_law_duration(phase_plane_knot_law(path, K, limits, lower, upper), task);
  };
  try {
    return 2 * fastest(fine) - fastest(half);
  } catch (const Error&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
}

double knot_law_duration(const std::vector<double>& x, double Tp) {
  const double delta = Tp / static_cast<double>(x.size() - 1);
  double T = 0;
  for (size_t i = 0; i + 1 < x.size(); ++i) T += 2 * delta / (std::sqrt(std::max(x[i], 0.0)) + std::sqrt(std::max(x[i + 1], 0.0)));
  return T;
}

}  // namespace refdyn
