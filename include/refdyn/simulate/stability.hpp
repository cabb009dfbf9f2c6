#pragma once
/// Linear stability of explicit steps: whether RK4 with step h is stable for ẋ = f(x) near a
/// state, from the eigenvalues λ of the exact Jacobian ∂f/∂x and RK4's stability function
///     R(z) = 1 + z + z²/2 + z³/6 + z⁴/24,   z = hλ,   stable where |R(z)| ≤ max(1, |e^z|)
/// (on the negative real axis for hλ ≥ −2.785; a mode that grows physically, Re λ > 0, may grow
/// as fast as the exact solution does). A run that fails with an unstable step is reported with
/// the step that would be stable — as stiff, with the advice to use method: bdf, when that step
/// is below 1 % of the one taken (plan.cpp) — before the symptom it ended with (a singular
/// partition, a NaN state, a residual above tolerance).
#include <Eigen/Core>

#include <complex>
#include <limits>

namespace refdyn {

struct StepStability {
  bool stable = true;
  std::complex<double> worst{0.0, 0.0};  ///< the eigenvalue with the largest |R(hλ)| / max(1, |e^{hλ}|)
  double spectral_radius = 0;            ///< max |λ|
  /// The largest step (≤ h) for which every eigenvalue is inside the region; h when stable.
  double largest_stable_step = std::numeric_limits<double>::infinity();
};

/// RK4's stability with step h for the Jacobian J (square, finite; Error otherwise).
StepStability rk4_step_stability(const Eigen::MatrixXd& J, double h);

}  // namespace refdyn
