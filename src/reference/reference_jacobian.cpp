// The exact Jacobian ∂f/∂x of the reference dynamics (reference_dynamics.hpp, jacobian()).
//
// f(t, x) = [q̇; q̈; ż], x = [q; q̇; z]. Whatever the solver (projection or Lagrange), q̈ and λ
// solve the KKT system
//     R₁ = M(q) q̈ + c(q, q̇) + g(q) − Q(t, q, q̇, z) + A(q, q̇)ᵀ λ = 0            (n rows)
//     R₂ = A(q, q̇) q̈ + b(q, q̇)                                   = 0            (m rows)
// with b = γ + 2αΦ̇ + β²Φ (holonomic rows), γ + β₁c (first-order rows), γ = s (acceleration
// rows): the stabilized constraint rows of derivative(). Differentiating along a direction δx
// at the solution (q̈*, λ*):
//     M δq̈ + Aᵀ δλ = −∂R₁/∂x δx,     A δq̈ = −∂R₂/∂x δx,
// where ∂R/∂x δx is R evaluated in dual numbers with q̈*, λ* held constant (one sweep gives
// kJacobianDirections directions; a sweep over force-state columns only evaluates the force
// elements, the only ones that read z). The KKT system is solved by the range-space method with the
// double M: δλ = S⁻¹(A M⁻¹ r₁ − r₂), δq̈ = M⁻¹(r₁ − Aᵀ δλ), S = A M⁻¹ Aᵀ.
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/dual_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace refdyn {

using D = JacobianScalar;
constexpr int kDir = kJacobianDirections;

struct ReferenceDynamics::JacobianWork {
  JacobianWork(const Model& model, const ConstraintSet& set, int nz)
      : data(model), ev(model, set), q(model.nq), qd(model.nq), qdd(model.nq), Q(model.nq), tau(model.nq),
        z(std::max(nz, 1)), zdot(std::max(nz, 1)) {}
  Data data;  // M in double
  ConstraintEvalDual ev;
  std::vector<D> q, qd, qdd, Q, tau, z, zdot;
  Eigen::MatrixXd r1, r2, MinvAt, S, tmp;
  Eigen::LLT<Eigen::MatrixXd> llt_M;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_S;
};

void ReferenceDynamics::jacobian(double t, const Eigen::VectorXd& x, Eigen::MatrixXd& J) {
  if (opt_.paper_literal_forces)
    throw Error("the exact Jacobian of the reference dynamics is not available with paper_literal_forces (its "
                "projected forces contain ∂Q/∂q̇ itself; hint: leave paper_literal_forces off to integrate with "
                "method: bdf)");
  const int n = n_, m = m_, nz = forces_.num_states(), nx = state_size();
  if (!jac_ || jac_.use_count() > 1) jac_ = std::make_shared<JacobianWork>(model_, constraints_, nz);
  JacobianWork& w = *jac_;
  if (static_cast<int>(xdot_.size()) != nx) xdot_.resize(nx);
  derivative(t, x, xdot_);  // q̈*, λ* (and the values of everything) at (t, x)

  J.setZero(nx, nx);
  for (int i = 0; i < n; ++i) J(i, n + i) = 1.0;  // ∂q̇/∂q̇ = I
  w.r1.resize(n, nx);
  w.r2.resize(m, nx);
  const double kd = 2.0 * opt_.alpha, kp = opt_.beta * opt_.beta, k1 = opt_.beta_first_order;
  for (int i = 0; i < n; ++i) w.qdd[i] = D(qdd_[i]);

  for (int c0 = 0; c0 < nx; c0 += kDir) {
    // Seed columns c0 … c0 + kDir − 1 of the state.
    auto seed = [&](int state_index, double value) {
      D v(value);
      const int k = state_index - c0;
      if (k >= 0 && k < kDir) v.d[k] = 1.0;
      return v;
    };
    for (int i = 0; i < n; ++i) {
      w.q[i] = seed(i, x[i]);
      w.qd[i] = seed(n + i, x[n + i]);
    }
    for (int i = 0; i < nz; ++i) w.z[i] = seed(2 * n + i, x[2 * n + i]);

    // Only the force elements read z: a sweep of force-state columns alone skips Newton–Euler
    // and the constraints (their derivatives along z are zero).
    const bool kinematic = c0 < 2 * n;
    if (kinematic) inverse_dynamics_dual(model_, w.q.data(), w.qd.data(), w.qdd.data(), true, w.tau.data());
    forces_.evaluate_dual(t, w.q.data(), w.qd.data(), w.z.data(), n, w.Q.data(), w.zdot.data());
    if (kinematic && m > 0) evaluate_constraints_dual(model_, constraints_, w.ev, t, w.q.data(), w.qd.data());

    const int cols = std::min(kDir, nx - c0);
    for (int i = 0; i < n; ++i) {
      D r = -w.Q[i];
      if (kinematic) {
        r += w.tau[i];
        for (int row = 0; row < m; ++row) r += w.ev.A[static_cast<size_t>(row) * n + i] * lambda_[row];
      }
      for (int k = 0; k < cols; ++k) w.r1(i, c0 + k) = -r.d[k];
    }
    if (!kinematic) w.r2.middleCols(c0, cols).setZero();
    for (int row = 0; kinematic && row < m; ++row) {
      D b = w.ev.gamma[row];
      if (acceleration_row_[row]) {
      } else if (first_order_row_[row]) {
        b += k1 * w.ev.phi[row];
      } else {
        b += kd * w.ev.phid[row] + kp * w.ev.phi[row];
      }
      for (int j = 0; j < n; ++j) b += w.ev.A[static_cast<size_t>(row) * n + j] * qdd_[j];
      for (int k = 0; k < cols; ++k) w.r2(row, c0 + k) = -b.d[k];
    }
    for (int i = 0; i < nz; ++i)
      for (int k = 0; k < cols; ++k) J(2 * n + i, c0 + k) = w.zdot[i].d[k];
  }

  // The KKT solve with the double M and A at (t, x).
  unchecked::crba(model_, w.data, q_);
  w.llt_M.compute(w.data.M);
  if (w.llt_M.info() != Eigen::Success)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite");
  Eigen::Block<Eigen::MatrixXd> dqdd = J.block(n, 0, n, nx);
  if (m == 0) {
    dqdd = w.llt_M.solve(w.r1);
    return;
  }
  const Eigen::MatrixXd& A = ev_.A;
  w.MinvAt = w.llt_M.solve(A.transpose());
  w.S.noalias() = A * w.MinvAt;
  w.lu_S.compute(w.S);
  w.tmp = w.llt_M.solve(w.r1);  // M⁻¹ r₁
  Eigen::MatrixXd dlambda = w.lu_S.solve(A * w.tmp - w.r2);
  dqdd = w.tmp - w.MinvAt * dlambda;
}

}  // namespace refdyn
