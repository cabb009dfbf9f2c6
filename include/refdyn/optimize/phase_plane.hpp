#pragma once
/// The phase-plane (TOPP-RA) method of `refdyn optimize` (docs/optimize.md, "method:
/// phase_plane"): the fastest knot-speed time law (expression/time_law.hpp, form knot_speeds)
/// of a task whose constraints fix the whole path, within the joints' effort and speed limits.
///
/// Along a fixed path q(τ) in task time τ, retimed by τ = s(t), the joint speeds are q'(τ) ṡ and
/// the rigid-body effort is
///     τ_eff = M q' s̈ + (M q'' + c(q, q')) ṡ² + g(q) = a(τ) s̈ + b(τ) ṡ² + c(τ),
/// linear in (s̈, x = ṡ²) (Bobrow, Shin–McKay; Pham's TOPP-RA). On the knot-speed law's parts
/// (x linear in τ on each part, s̈ = (x_{i+1} − x_i)/(2Δτ)) every limit at every path sample is a
/// linear inequality in the two knot values (x_i, x_{i+1}); a backward pass gives the largest
/// controllable x at each knot, a forward pass the greedy (largest) admissible x — the time
/// optimum among the laws on these knots (Pham & Pham 2018). Σ 2Δτ/(√x_i + √x_{i+1}) is the end.
///
///   path_dynamics(plan of the task without its law)  → PathDynamics {τ_k, a_k, b_k, c_k, q'_k}
///   phase_plane_knot_law(path, K, limits, bounds)     → x_0 … x_K
#include "refdyn/multibody/model.hpp"
#include "refdyn/simulate/trajectory.hpp"

#include <Eigen/Core>
#include <vector>

namespace refdyn {

/// The path's coefficients at the samples of a plan made in task time (ṡ = 1, s̈ = 0).
struct PathDynamics {
  std::vector<double> tau;               ///< task time of each sample (increasing)
  std::vector<Eigen::VectorXd> a, b, c;  ///< effort = a s̈ + b ṡ² + c (per joint)
  std::vector<Eigen::VectorXd> dq;       ///< q'(τ): joint speed = q' ṡ
  double worst_effort_mismatch = 0;      ///< max |plan's actuator effort − (b + c)| [N m or N]
};

/// a, b, c by the recursive Newton–Euler algorithm at each sample (q, q' = q̇, q'' = q̈) of
/// `plan`, a plan of the task in its own time. Throws Error when the plan's actuator effort is
/// not the rigid-body inverse dynamics of its samples (force elements, material constraints:
/// the effort is then not of the form a s̈ + b ṡ² + c) — more than 1e-6 (1 + |τ|) at some sample.
PathDynamics path_dynamics(const Model& model, const Plan& plan);

/// Symmetric limits |τ_j| ≤ effort_j, |q̇_j| ≤ speed_j (infinite: none).
struct PhasePlaneLimits {
  Eigen::VectorXd effort, speed;
};

/// TOPP-RA on K equal parts of [0, Tp] (Tp = the path's last τ): x_0 = x_K = 0 (rest to rest),
/// x_i ∈ [lower_i, upper_i] for 0 < i < K (the squared bounds of the knot speeds; vectors of
/// K + 1 entries, the ends ignored). The limits are imposed at every path sample of every part.
/// Returns x_0 … x_K. Throws Error naming the knot when no law on the knots is admissible.
std::vector<double> phase_plane_knot_law(const PathDynamics& path, int K, const PhasePlaneLimits& limits,
                                         const std::vector<double>& lower, const std::vector<double>& upper);

/// The path's time optimum T* under the limits, estimated (the distance of a K-part law from it,
/// docs/optimize.md): the fastest laws with a knot at every path sample (K_f parts) and at every
/// second one (K_f/2 parts), extrapolated as T* ≈ 2 T(K_f) − T(K_f/2), the fastest K-part law
/// being T* + C/K + o(1/K) (s̈ constant on a part of width Δτ loses O(Δτ) of the slope the limits
/// allow). Every knot's x is at most max_x (the knot speeds' largest bound, squared). NaN when no
/// law on those knots is admissible.
double phase_plane_time_optimum(const PathDynamics& path, const PhasePlaneLimits& limits, double max_x);

/// The real duration of the knot-speed law x_0 … x_K over Tp: Σ 2Δτ/(√x_i + √x_{i+1}).
double knot_law_duration(const std::vector<double>& x, double Tp);

}  // namespace refdyn
