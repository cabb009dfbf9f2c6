#pragma once
// Independent reference for time-optimal path following (TOPP) of a fully actuated arm along a
// fixed path, for the retiming tests (issue 23, item 4c). Nothing here uses refdyn's engine.
//
// Along a path q(θ), θ ∈ [0, θ_end], the joint efforts are τ = a(θ) θ̈ + b(θ) θ̇² + c(θ) with
// a = M q', b = M q'' + C(q, q') q', c = g(q). In the phase plane (θ, x = θ̇²), θ̈ = u = x'/2.
// Method: the phase plane discretized on a uniform grid θ_0 … θ_N with u constant on each step
// (x_{i+1} = x_i + 2Δ u_i), effort limits |τ_j| ≤ τmax_j imposed at θ_i with (x_i, u_i), speed
// limits |q'_j| θ̇ ≤ vmax_j: the maximum velocity curve, a backward pass of maximum deceleration
// (the controllable sets: the largest x_i from which x_N = 0 can be reached, each step an exact
// two-variable LP) and a forward pass of maximum acceleration from x_0 = 0 clipped to them — the
// discrete form of the Bobrow / Shin–McKay bang-bang construction (forward max-acceleration
// curves, backward max-deceleration curves from the end and from the MVC's switching points,
// whose envelope the backward pass computes); Pham & Pham's TOPP-RA (2018). Rest to rest:
// x_0 = x_N = 0. T = Σ 2Δ/(√x_i + √x_{i+1}). Exact for a double integrator (u piecewise
// constant); first order in Δ in general (the tests check convergence under grid refinement).
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace refdyn::test {

/// The path's dynamics sampled on the grid: per grid point the vectors a, b, c and q' (n joints).
struct PathDynamics {
  double theta_end = 0;
  std::vector<Eigen::VectorXd> a, b, c, dq;  ///< N + 1 samples each
};

struct ToppLimits {
  Eigen::VectorXd tau_max;  ///< |τ_j| ≤ tau_max_j (infinity: none)
  Eigen::VectorXd v_max;    ///< |q̇_j| ≤ v_max_j (infinity: none)
};

namespace topp_detail {
constexpr double kInf = std::numeric_limits<double>::infinity();

/// max x subject to rows (α_k x + β_k u ≤ γ_k): the exact 2-variable LP by vertex enumeration
/// (returns −1 if infeasible). The feasible set is bounded in x by the caller's x ≤ xmax row.
inline double max_x(const std::vector<Eigen::Vector3d>& rows) {
  double best = -1;
  const double tol = 1e-9;
  auto feasible = [&](double x, double u) {
    for (const auto& r : rows)
      if (r[0] * x + r[1] * u > r[2] + tol * (1 + std::abs(r[2]))) return false;
    return true;
  };
  for (size_t i = 0; i < rows.size(); ++i)
    for (size_t j = i + 1; j < rows.size(); ++j) {
      const double det = rows[i][0] * rows[j][1] - rows[i][1] * rows[j][0];
      if (std::abs(det) < 1e-14) continue;
      const double x = (rows[i][2] * rows[j][1] - rows[i][1] * rows[j][2]) / det;
      const double u = (rows[i][0] * rows[j][2] - rows[i][2] * rows[j][0]) / det;
      if (feasible(x, u)) best = std::max(best, x);
    }
  return best;
}

/// Rows of the constraints at grid point i in (x, u): efforts, speeds, x ≥ 0, x ≤ xcap.
inline std::vector<Eigen::Vector3d> rows_at(const PathDynamics& p, const ToppLimits& L, size_t i, double xcap) {
  std::vector<Eigen::Vector3d> r;
  for (int j = 0; j < p.a[i].size(); ++j) {
    if (std::isfinite(L.tau_max[j])) {
      r.emplace_back(p.b[i][j], p.a[i][j], L.tau_max[j] - p.c[i][j]);     //  τ ≤ τmax
      r.emplace_back(-p.b[i][j], -p.a[i][j], L.tau_max[j] + p.c[i][j]);   // −τ ≤ τmax
    }
    if (std::isfinite(L.v_max[j]) && std::abs(p.dq[i][j]) > 0)
      r.emplace_back(p.dq[i][j] * p.dq[i][j], 0.0, L.v_max[j] * L.v_max[j]);
  }
  r.emplace_back(-1.0, 0.0, 0.0);
  r.emplace_back(1.0, 0.0, xcap);
  return r;
}

/// The interval [lo, hi] of feasible u at (i, x) (lo > hi: none).
inline std::pair<double, double> u_range(const PathDynamics& p, const ToppLimits& L, size_t i, double x) {
  double lo = -kInf, hi = kInf;
  for (int j = 0; j < p.a[i].size(); ++j) {
    if (!std::isfinite(L.tau_max[j])) continue;
    const double a = p.a[i][j], rest = p.b[i][j] * x + p.c[i][j];
    if (std::abs(a) < 1e-14) {
      if (std::abs(rest) > L.tau_max[j]) return {1, -1};
      continue;
    }
    double u1 = (-L.tau_max[j] - rest) / a, u2 = (L.tau_max[j] - rest) / a;
    if (u1 > u2) std::swap(u1, u2);
    lo = std::max(lo, u1);
    hi = std::min(hi, u2);
  }
  return {lo, hi};
}
}  // namespace topp_detail

/// The optimal profile x_i = θ̇² at the grid points θ_i (empty when no admissible traversal exists).
inline std::vector<double> topp_profile(const PathDynamics& p, const ToppLimits& L) {
  using namespace topp_detail;
  const size_t N = p.a.size() - 1;
  const double h = p.theta_end / static_cast<double>(N);
  const double big = 1e12;
  // backward pass: K_i = max x_i with a feasible u and x_i + 2hu ∈ [0, K_{i+1}]
  std::vector<double> K(N + 1, 0.0);
  K[N] = 0.0;
  for (size_t i = N; i-- > 0;) {
    auto r = rows_at(p, L, i, big);
    r.emplace_back(1.0, 2 * h, K[i + 1]);
    r.emplace_back(-1.0, -2 * h, 0.0);
    K[i] = max_x(r);
    if (K[i] < 0) return {};
  }
  // forward pass: maximum acceleration from x_0 = 0, kept inside the controllable sets
  std::vector<double> x(N + 1, 0.0);
  for (size_t i = 0; i < N; ++i) {
    const auto [lo, hi] = u_range(p, L, i, x[i]);
    double u = std::min(hi, (K[i + 1] - x[i]) / (2 * h));
    u = std::max(u, lo);  // within rounding of the LP: stay admissible
    x[i + 1] = std::clamp(x[i] + 2 * h * u, 0.0, K[i + 1]);
  }
  return x;
}

/// The minimum rest-to-rest traversal time of the sampled path (see the file's comment);
/// infinity when no admissible traversal exists.
inline double topp_min_time(const PathDynamics& p, const ToppLimits& L) {
  using namespace topp_detail;
  const std::vector<double> x = topp_profile(p, L);
  if (x.empty()) return kInf;
  const size_t N = x.size() - 1;
  const double h = p.theta_end / static_cast<double>(N);
  double T = 0;
  for (size_t i = 0; i < N; ++i) {
    const double s = std::sqrt(x[i]) + std::sqrt(x[i + 1]);
    if (!(s > 0)) return kInf;
    T += 2 * h / s;
  }
  return T;
}

/// The planar 2R arm of examples/planar_2r_circle (vertical x-y plane, gravity g along −y): links
/// of length L_i, mass m_i at L_i/2, inertia about the centre of mass m_i L_i²/12.
struct TwoLinkArm {
  double L1 = 0.5, L2 = 0.4, m1 = 2.0, m2 = 1.5, g = 9.81;
  /// M(q), the Coriolis/centrifugal vector C(q, q̇) q̇ and g(q), written by hand.
  Eigen::Matrix2d M(const Eigen::Vector2d& q) const {
    const double lc1 = L1 / 2, lc2 = L2 / 2, I1 = m1 * L1 * L1 / 12, I2 = m2 * L2 * L2 / 12, c2 = std::cos(q[1]);
    Eigen::Matrix2d m;
    m(0, 0) = I1 + I2 + m1 * lc1 * lc1 + m2 * (L1 * L1 + lc2 * lc2 + 2 * L1 * lc2 * c2);
    m(0, 1) = m(1, 0) = I2 + m2 * (lc2 * lc2 + L1 * lc2 * c2);
    m(1, 1) = I2 + m2 * lc2 * lc2;
    return m;
  }
  Eigen::Vector2d coriolis(const Eigen::Vector2d& q, const Eigen::Vector2d& qd) const {
    const double hh = -m2 * L1 * (L2 / 2) * std::sin(q[1]);
    return {hh * (2 * qd[0] * qd[1] + qd[1] * qd[1]), -hh * qd[0] * qd[0]};
  }
  Eigen::Vector2d gravity(const Eigen::Vector2d& q) const {
    const double c1 = std::cos(q[0]), c12 = std::cos(q[0] + q[1]);
    return {(m1 * L1 / 2 + m2 * L1) * g * c1 + m2 * (L2 / 2) * g * c12, m2 * (L2 / 2) * g * c12};
  }
  Eigen::Vector2d inverse_dynamics(const Eigen::Vector2d& q, const Eigen::Vector2d& qd, const Eigen::Vector2d& qdd) const {
    return M(q) * qdd + coriolis(q, qd) + gravity(q);
  }
};

/// The circle E(θ) = (cx + R cos θ, cy + R sin θ), θ ∈ [0, 2π] (one turn, counter-clockwise).
struct Circle {
  double cx = 0.6, cy = 0.2, R = 0.15;
};

/// Closed-form inverse kinematics (elbow q2 = +acos, as the example) and its θ-derivatives
/// q' and q'' (from J q' = E', J q'' = E'' − J̇(q') q').
inline void circle_ik(const TwoLinkArm& arm, const Circle& c, double th, Eigen::Vector2d& q, Eigen::Vector2d& dq,
                      Eigen::Vector2d& ddq) {
  const double ex = c.cx + c.R * std::cos(th), ey = c.cy + c.R * std::sin(th);
  q[1] = std::acos((ex * ex + ey * ey - arm.L1 * arm.L1 - arm.L2 * arm.L2) / (2 * arm.L1 * arm.L2));
  q[0] = std::atan2(ey, ex) - std::atan2(arm.L2 * std::sin(q[1]), arm.L1 + arm.L2 * std::cos(q[1]));
  const double s1 = std::sin(q[0]), c1 = std::cos(q[0]), s12 = std::sin(q[0] + q[1]), c12 = std::cos(q[0] + q[1]);
  Eigen::Matrix2d J;
  J << -arm.L1 * s1 - arm.L2 * s12, -arm.L2 * s12, arm.L1 * c1 + arm.L2 * c12, arm.L2 * c12;
  const Eigen::Vector2d dE(-c.R * std::sin(th), c.R * std::cos(th)), ddE(-c.R * std::cos(th), -c.R * std::sin(th));
  dq = J.partialPivLu().solve(dE);
  const double w1 = dq[0], w12 = dq[0] + dq[1];
  const Eigen::Vector2d Jdq(-arm.L1 * c1 * w1 * w1 - arm.L2 * c12 * w12 * w12, -arm.L1 * s1 * w1 * w1 - arm.L2 * s12 * w12 * w12);
  ddq = J.partialPivLu().solve(ddE - Jdq);
}

inline PathDynamics circle_path(const TwoLinkArm& arm, const Circle& c, int N) {
  PathDynamics p;
  p.theta_end = 2 * std::numbers::pi;
  for (int i = 0; i <= N; ++i) {
    Eigen::Vector2d q, dq, ddq;
    circle_ik(arm, c, p.theta_end * i / N, q, dq, ddq);
    const Eigen::Matrix2d M = arm.M(q);
    p.a.push_back(M * dq);
    p.b.push_back(M * ddq + arm.coriolis(q, dq));
    p.c.push_back(arm.gravity(q));
    p.dq.push_back(dq);
  }
  return p;
}

/// T* of one rest-to-rest turn of the circle under |τ_j| ≤ τmax_j (and |q̇_j| ≤ vmax_j).
inline double topp_min_time(const TwoLinkArm& arm, const Circle& c, const ToppLimits& L, int N = 20000) {
  return topp_min_time(circle_path(arm, c, N), L);
}

/// The fastest traversal by a knot-speed time law (docs/scenario.md "time_law", knot_speeds):
/// K equal parts of θ ∈ [0, θ_end], x = θ̇² linear in θ on each part (constant θ̈, the TOPP-RA
/// discretisation), x_0 = x_K = 0, with the limits imposed at M + 1 points of every part (not
/// only at the knots): on part i every constraint is linear in (x_i, u_i), u_i = (x_{i+1} − x_i)/(2H),
/// since at θ_i + δ, x = x_i + 2u_i δ and τ = a u_i + b x + c. Backward: the largest controllable
/// x_i (the 2-variable LP max_x); forward: the largest admissible u_i. Returns x_0 … x_K (empty:
/// no admissible law); the law's time is Σ 2H/(√x_i + √x_{i+1}).
inline std::vector<double> topp_knot_law(const TwoLinkArm& arm, const Circle& c, const ToppLimits& L, int K, int M) {
  using namespace topp_detail;
  const PathDynamics p = circle_path(arm, c, K * M);
  const double H = p.theta_end / K, hf = H / M;
  auto rows_part = [&](int i) {
    std::vector<Eigen::Vector3d> r;
    for (int f = 0; f <= M; ++f) {
      const size_t g = static_cast<size_t>(i * M + f);
      const double d = f * hf;
      for (int j = 0; j < p.a[g].size(); ++j) {
        const double a = p.a[g][j], b = p.b[g][j], cc = p.c[g][j];
        if (std::isfinite(L.tau_max[j])) {
          r.emplace_back(b, a + 2 * b * d, L.tau_max[j] - cc);
          r.emplace_back(-b, -(a + 2 * b * d), L.tau_max[j] + cc);
        }
        if (std::isfinite(L.v_max[j])) {
          const double q2 = p.dq[g][j] * p.dq[g][j];
          r.emplace_back(q2, 2 * q2 * d, L.v_max[j] * L.v_max[j]);
        }
      }
      r.emplace_back(-1.0, -2 * d, 0.0);  // x ≥ 0 inside the part
    }
    r.emplace_back(-1.0, 0.0, 0.0);
    r.emplace_back(1.0, 0.0, 1e12);
    return r;
  };
  std::vector<double> Kc(static_cast<size_t>(K) + 1, 0.0);
  for (int i = K; i-- > 1;) {
    auto r = rows_part(i);
    r.emplace_back(1.0, 2 * H, Kc[static_cast<size_t>(i) + 1]);
    Kc[static_cast<size_t>(i)] = max_x(r);
    if (Kc[static_cast<size_t>(i)] < 0) return {};
  }
  std::vector<double> x(static_cast<size_t>(K) + 1, 0.0);
  for (int i = 0; i + 1 < K; ++i) {
    auto r = rows_part(i);
    r.emplace_back(1.0, 2 * H, Kc[static_cast<size_t>(i) + 1]);
    double uhi = kInf;
    for (const auto& row : r)
      if (row[1] > 1e-15) uhi = std::min(uhi, (row[2] - row[0] * x[static_cast<size_t>(i)]) / row[1]);
    x[static_cast<size_t>(i) + 1] = std::clamp(x[static_cast<size_t>(i)] + 2 * H * uhi, 0.0, Kc[static_cast<size_t>(i) + 1]);
    if (!(x[static_cast<size_t>(i) + 1] > 0)) return {};
  }
  return x;
}

}  // namespace refdyn::test
