// rk4_step_stability (stability.hpp).
#include "refdyn/simulate/stability.hpp"

#include "refdyn/common/error.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>

namespace refdyn {

namespace {
/// RK4's amplification |R(z)| beyond what the exact solution does over the step: a mode that
/// grows physically (Re λ > 0, e.g. an arm falling away from an unstable equilibrium) grows by
/// |e^z| and RK4 may follow it; only growth beyond max(1, |e^z|) is a numerical instability.
double rk4_amplification(std::complex<double> z) {
  const double r = std::abs(1.0 + z * (1.0 + z * (0.5 + z * (1.0 / 6.0 + z / 24.0))));
  return r / std::max(1.0, std::exp(z.real()));
}
double worst_amplification(const Eigen::VectorXcd& lambda, double h) {
  double worst = 0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) worst = std::max(worst, rk4_amplification(h * lambda[i]));
  return worst;
}
}  // namespace

StepStability rk4_step_stability(const Eigen::MatrixXd& J, double h) {
  if (J.rows() != J.cols() || !J.allFinite() || !(h > 0) || !std::isfinite(h))
    throw Error("rk4_step_stability: expected a finite square Jacobian and a step > 0");
  StepStability s;
  if (J.size() == 0) {
    s.largest_stable_step = h;
    return s;
  }
  const Eigen::VectorXcd lambda = Eigen::EigenSolver<Eigen::MatrixXd>(J, false).eigenvalues();
  double worst = -1;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    s.spectral_radius = std::max(s.spectral_radius, std::abs(lambda[i]));
    const double a = rk4_amplification(h * lambda[i]);
    if (a > worst) worst = a, s.worst = lambda[i];
  }
  // A small tolerance: eigenvalues on the imaginary axis (undamped modes) have |R| slightly
  // above 1 for any h (RK4's region touches the axis only near 0), which is not a blow-up.
  const double tol = 1e-6;
  s.stable = worst <= 1.0 + tol;
  if (s.stable) {
    s.largest_stable_step = h;
    return s;
  }
  double lo = 0, hi = h;  // bisection for the largest stable step along the ray of step sizes
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (worst_amplification(lambda, mid) <= 1.0 + tol ? lo : hi) = mid;
  }
  s.largest_stable_step = lo;
  return s;
}

}  // namespace refdyn
