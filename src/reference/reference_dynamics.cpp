// ReferenceDynamics' evaluation (reference_dynamics.hpp): derivative() and its stages, the
// partition's factorization and the solves for q̈ and λ (projection with the partitioned or the
// orthonormal basis, Lagrange with Cholesky or ABA), in one translation unit so that the hot
// path inlines across its stages. Construction, the partition's choice and the consistent
// initial state are in reference_setup.cpp.
#include "refdyn/reference/reference_dynamics.hpp"

#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

namespace refdyn {

namespace {
/// Inverse of a small M×M matrix with Eigen's fixed-size closed form; false when singular.
template <int M>
bool small_inverse(const Eigen::MatrixXd& K, Eigen::MatrixXd& Kinv) {
  const Eigen::Matrix<double, M, M> k = K;
  Eigen::Matrix<double, M, M> inv;
  double det = 0;
  bool ok = false;
  k.computeInverseAndDetWithCheck(inv, det, ok, 0.0);
  if (!ok || !std::isfinite(det)) return false;
  Kinv = inv;
  return true;
}
}  // namespace

namespace {
/// The force the projection routes project: f = F, or F + (∂Q/∂q̇)ᵀ q̇ with paper-literal forces.
void projected_force(bool paper_literal, const Eigen::MatrixXd& dQ, const Eigen::VectorXd& qd,
                     const Eigen::VectorXd& F, Eigen::VectorXd& f) {
  if (paper_literal) {
    f.noalias() = dQ.transpose() * qd;
    f += F;
  } else {
    f = F;
  }
}
}  // namespace

#include "sized_dispatch.hpp"  // REFDYN_FIXED_DISPATCH, REFDYN_SIZED_DISPATCH (why: there)

bool ReferenceDynamics::factor_partition() {
  cond_current_ = true;  // every return of factor_partition_sized sets cond_
  REFDYN_SIZED_DISPATCH(factor_partition_sized, ())
}

double ReferenceDynamics::partition_condition() {
  if (!cond_current_ && partition_set_ && m_ > 0) factor_partition();  // the orthonormal route did not
  return cond_;
}

template <int N, int Mr>
bool ReferenceDynamics::factor_partition_sized() {
  const int n = N > 0 ? N : n_, m = N > 0 ? Mr : m_, k = n - m;
  const int* __restrict dep = dep_.data();
  const int* __restrict ind = ind_.data();
  const double* __restrict A = ev_.A.data();  // m × n, column-major
  double* Kdc = Kdc_.data();  // also read by small_inverse through Kdc_: no restrict
  double* __restrict Kic = Kic_.data();
  for (int c = 0; c < m; ++c)
    for (int r = 0; r < m; ++r) Kdc[c * m + r] = A[dep[c] * m + r];
  for (int c = 0; c < k; ++c)
    for (int r = 0; r < m; ++r) Kic[c * m + r] = A[ind[c] * m + r];
  if (m == 0) {
    cond_ = 1.0;
    return true;
  }
  // K_dc⁻¹: Eigen's closed-form fixed-size inverse for m ≤ 4 (the common case), else an LU
  // applied in place (U⁻¹ L⁻¹ P, no temporaries). A singular K_dc gives an infinite κ.
  bool regular = true;
  if constexpr (N > 0) regular = small_inverse<Mr>(Kdc_, Kinv_);
  else switch (m) {
    case 1: regular = small_inverse<1>(Kdc_, Kinv_); break;
    case 2: regular = small_inverse<2>(Kdc_, Kinv_); break;
    case 3: regular = small_inverse<3>(Kdc_, Kinv_); break;
    case 4: regular = small_inverse<4>(Kdc_, Kinv_); break;
    default: {
      lu_m_.compute(Kdc_);
      Kinv_.setZero();
      const auto& perm = lu_m_.permutationP().indices();  // P e_i = e_perm[i]
      for (int i = 0; i < m; ++i) Kinv_(perm[i], i) = 1.0;
      lu_m_.matrixLU().triangularView<Eigen::UnitLower>().solveInPlace(Kinv_);
      lu_m_.matrixLU().triangularView<Eigen::Upper>().solveInPlace(Kinv_);
    }
  }
  if (!regular) {
    cond_ = std::numeric_limits<double>::infinity();
    return false;
  }
  auto norm1 = [](const double* __restrict X, int rows, int cols) {  // max column abs sum
    double best = 0;
    for (int c = 0; c < cols; ++c) {
      double sum = 0;
      for (int r = 0; r < rows; ++r) sum += std::abs(X[c * rows + r]);
      best = std::max(best, sum);
    }
    return best;
  };
  const double* __restrict Ki = Kinv_.data();
  // κ = ‖A‖₁ ‖K_dc⁻¹‖₁: the sensitivity of q̇_dc = −K_dc⁻¹ K_ic q̇_ic, measured against the whole
  // constraint Jacobian (a tiny K_dc next to a large K_ic is ill-conditioned even when m = 1).
  const double norm = norm1(A, m, n);
  const double inorm = norm1(Ki, m, m);
  const double cond = norm * inorm;
  cond_ = cond;
  if (!std::isfinite(cond) || cond > opt_.max_condition || norm == 0) return false;
  // G = −K_dc⁻¹ K_ic (m × k)
  double* __restrict G = G_.data();
  for (int c = 0; c < k; ++c)
    for (int r = 0; r < m; ++r) {
      double sum = 0;
      for (int j = 0; j < m; ++j) sum += Ki[j * m + r] * Kic[c * m + j];
      G[c * m + r] = -sum;
    }
  return true;
}

// ẋ = [q̇; q̈; ż], stage by stage (each stage is a member below, in this order).
void ReferenceDynamics::derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  read_state(t, x, xdot);
  factored_ = false;
  cond_current_ = false;
  const double* z = forces_.num_states() ? x.data() + 2 * n_ : nullptr;
  if (aba_) {  // no constraint rows, a large model: q̈ = M⁻¹(Q − c − g) by the articulated-body algorithm
    unconstrained_aba(t, z);
    write_derivative(xdot);
    return;
  }
  bias_and_constraints(t);  // M and c + g in one sweep; Φ, Φ̇, A, γ reusing its body motions
  forces_and_solve(t, x, xdot);
}

void ReferenceDynamics::prepare_derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  read_state(t, x, xdot);
  factored_ = false;
  cond_current_ = false;
  if (aba_) return;
  bias_and_constraints(t);
  if (opt_.solver == ReferenceSolver::Projection && m_ > 0) {  // a function of A alone: done here, shared
    factor_for_projection(t);
    factored_ = true;
  }
}

void ReferenceDynamics::complete_derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  if (aba_) {
    unconstrained_aba(t, forces_.num_states() ? x.data() + 2 * n_ : nullptr);
    write_derivative(xdot);
    return;
  }
  forces_and_solve(t, x, xdot);
}

// After bias_and_constraints: Q, ż, the right-hand side, q̈ and λ, Q_c, ẋ.
void ReferenceDynamics::forces_and_solve(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  const double* z = forces_.num_states() ? x.data() + 2 * n_ : nullptr;
  forces_.evaluate(t, q_, qd_, z, Q_, zdot_.data(), opt_.paper_literal_forces ? &dQ_ : nullptr);  // Q, ż
  stabilized_rhs();         // F = Q − c − g; the stabilized right-hand side of A q̈ = rhs
  if (opt_.solver == ReferenceSolver::Projection)  // q̈ and λ
    solve_projection(t);
  else if (aba_lagrange_)
    solve_lagrange_aba(t);
  else
    solve_lagrange(t);
  constraint_forces();      // Q_c (and, for projection, λ from the dependent rows)
  if (has_acceleration_rows_) acceleration_residuals();
  write_derivative(xdot);
}

// q = x[0, n), q̇ = x[n, 2n) into the workspaces; sizes and finiteness checked.
void ReferenceDynamics::read_state(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& xdot) {
  if (x.size() != state_size() || xdot.size() != state_size()) {
    check_size("x", state_size(), x.size(), "x = [q; qd; z] with z the force-element states");
    check_size("xdot", state_size(), xdot.size());
  }
  {  // A NaN or infinity in x makes the sum non-finite; only then is the exact check needed.
    const double* __restrict xp = x.data();
    double sum = 0;
    for (Eigen::Index i = 0; i < x.size(); ++i) sum += xp[i];
    if (!std::isfinite(sum) && !x.allFinite())
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the state is not finite (NaN or infinity)");
  }
  q_ = x.head(n_);
  qd_ = x.segment(n_, n_);
}

// No constraint rows, a large model: q̈ = M⁻¹(Q − c − g) by ABA, Q_c = 0.
void ReferenceDynamics::unconstrained_aba(double t, const double* z) {
  forces_.evaluate(t, q_, qd_, z, Q_, zdot_.data(), opt_.paper_literal_forces ? &dQ_ : nullptr);
  tmp_n_ = Q_;
  if (opt_.paper_literal_forces) tmp_n_.noalias() += dQ_.transpose() * qd_;
  if (unchecked::aba(model_, data_, q_, qd_, tmp_n_, qdd_) >= 0)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite");
  Qc_.setZero();
}

// One set of joint placements per evaluation, computed with M and c + g in one sweep; the
// constraint kinematics reuse them and RNEA's body velocities and accelerations.
void ReferenceDynamics::bias_and_constraints(double t) {
  if (aba_lagrange_)  // c + g and the body motions the constraints read; M is not needed
    unchecked::rnea(model_, data_, q_, &qd_, nullptr, true, data_.nle);
  else
    unchecked::mass_matrix_and_bias(model_, data_, q_, qd_);
  evaluate_constraints_after_bias_forces(model_, data_, constraints_, ev_, t, q_, qd_);
}

// F = Q − c − g, and the right-hand side of A q̈ = rhs: Baumgarte Φ̈ + 2αΦ̇ + β²Φ = 0
// (holonomic rows), ċ + β₁c = 0 (first-order rows), B q̈ + s = 0 as it is (acceleration rows).
void ReferenceDynamics::stabilized_rhs() {
  const int n = n_, m = m_;
  const double* __restrict Q = Q_.data();
  const double* __restrict nle = data_.nle.data();
  double* __restrict F = F_.data();
  for (int i = 0; i < n; ++i) F[i] = Q[i] - nle[i];
  const double* __restrict gamma = ev_.gamma.data();
  const double* __restrict phi = ev_.phi.data();
  const double* __restrict phid = ev_.phid.data();
  const char* __restrict first = first_order_row_.data();
  const double kd = 2.0 * opt_.alpha, kp = opt_.beta * opt_.beta, k1 = opt_.beta_first_order;
  double* __restrict rhs = rhs_.data();
  if (!has_acceleration_rows_) {
    for (int r = 0; r < m; ++r) rhs[r] = first[r] ? -gamma[r] - k1 * phi[r] : -gamma[r] - kd * phid[r] - kp * phi[r];
  } else {  // acceleration rows B q̈ + s = 0 (order p = 2): imposed as they are, A = B, γ = s
    const char* __restrict acc = acceleration_row_.data();
    for (int r = 0; r < m; ++r)
      rhs[r] = acc[r] ? -gamma[r] : first[r] ? -gamma[r] - k1 * phi[r] : -gamma[r] - kd * phid[r] - kp * phi[r];
  }
}

// Q_c = M q̈ − F (or −Aᵀλ where M is not formed); projection with the partition: λ from the
// dependent rows, K_dcᵀλ = −Q_c,dc (the orthonormal solve gives λ with q̈, from its QR).
void ReferenceDynamics::constraint_forces() {
  const int n = n_, m = m_;
  const double* __restrict qdd = qdd_.data();
  const double* __restrict F = F_.data();
  double* __restrict Qc = Qc_.data();
  if (aba_lagrange_) {  // Q_c = −Aᵀλ (M is not formed)
    const double* __restrict A = ev_.A.data();  // m × n, column-major
    const double* __restrict lambda = lambda_.data();
    for (int i = 0; i < n; ++i) {
      double sum = 0;
      for (int r = 0; r < m; ++r) sum -= A[static_cast<size_t>(i) * m + r] * lambda[r];
      Qc[i] = sum;
    }
  } else {  // Q_c = M q̈ − F
    const double* __restrict Mp = data_.M.data();
    for (int i = 0; i < n; ++i) Qc[i] = -F[i];
    for (int j = 0; j < n; ++j) {
      const double a = qdd[j];
      const double* __restrict col = Mp + static_cast<size_t>(j) * n;
      for (int i = 0; i < n; ++i) Qc[i] += a * col[i];
    }
  }
  if (opt_.solver == ReferenceSolver::Projection && m > 0 && !orthonormal_) {  // (the orthonormal solve gave λ)
    const double* __restrict Ki = Kinv_.data();
    const int* __restrict dep = dep_.data();
    double* __restrict lambda = lambda_.data();
    for (int c = 0; c < m; ++c) {
      double sum = 0;
      for (int r = 0; r < m; ++r) sum -= Ki[c * m + r] * Qc[dep[r]];  // (K⁻¹)ᵀ(c, r) = K⁻¹(r, c)
      lambda[c] = sum;
    }
  }
}

void ReferenceDynamics::write_derivative(Eigen::VectorXd& xdot) const {
  const int n = n_, nz = forces_.num_states();
  double* __restrict out = xdot.data();
  const double* __restrict qd = qd_.data();
  const double* __restrict qdd = qdd_.data();
  for (int i = 0; i < n; ++i) out[i] = qd[i];
  for (int i = 0; i < n; ++i) out[n + i] = qdd[i];
  const double* __restrict zd = zdot_.data();
  for (int i = 0; i < nz; ++i) out[2 * n + i] = zd[i];
}

void ReferenceDynamics::acceleration_residuals() {
  // The residual of an acceleration row is B q̈ + s, known only after the solve: it is written
  // where a holonomic row has Φ and Φ̇ (recorded, reported), so that plans show it.
  for (int r = 0; r < m_; ++r)
    if (acceleration_row_[r]) {
      const double res = ev_.A.row(r).dot(qdd_) + ev_.gamma[r];
      ev_.phi[r] = res;
      ev_.phid[r] = res;
    }
}

double ReferenceDynamics::residual(double t, const Eigen::VectorXd& x) {
  check_size("x", state_size(), x.size());
  if (has_acceleration_rows_) {  // their residual B q̈ + s needs q̈: one evaluation of the dynamics
    xdot_.resize(state_size());
    derivative(t, x, xdot_);
    return ev_.phi.cwiseAbs().maxCoeff();
  }
  q_ = x.head(n_);
  qd_ = x.segment(n_, n_);
  evaluate_constraints(model_, data_, constraints_, ev_, t, q_, qd_);
  return m_ ? ev_.phi.cwiseAbs().maxCoeff() : 0.0;
}

// (Nᵀ M N) u = r in place (NMN_, rk_; k independent coordinates): a scalar division for k = 1
// (the paper's case), else a Cholesky factorization. The partitioned route ends with it (the
// orthonormal one factors Zᵀ M Z in OrthonormalNullSpaceSolve).
void ReferenceDynamics::solve_reduced_mass(double t, int k) {
  double* NMN = NMN_.data();
  double* rk = rk_.data();
  if (k == 1) {
    if (!(NMN[0] > 0))
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the reduced mass matrix Nᵀ M N is not positive definite");
    rk[0] /= NMN[0];
  } else {
    llt_k_.compute(NMN_);
    if (llt_k_.info() != Eigen::Success)
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the reduced mass matrix Nᵀ M N is not positive definite");
    llt_k_.solveInPlace(rk_);
  }
}

void ReferenceDynamics::factor_for_projection(double t) {
  if (!partition_set_) choose_partition(t, q_, qd_), evaluate_constraints(model_, data_, constraints_, ev_, t, q_, qd_);
  if (!factor_partition()) {
    if (!opt_.automatic_partition) throw NumericalFailure(t, partition_message(t));
    choose_partition(t, q_, qd_);
    if (!factor_partition()) throw NumericalFailure(t, partition_message(t));
  }
}

void ReferenceDynamics::solve_projection(double t) {
  // The small fixed sizes (the paper's example among them) keep the partitioned basis N, and
  // m = n solves with K_dc⁻¹: both factor the partition. Every other size takes the orthonormal
  // basis, which does not use the partition (see the header comment); it is only chosen, once.
  if (orthonormal_) {
    if (!partition_set_) choose_partition(t, q_, qd_), evaluate_constraints(model_, data_, constraints_, ev_, t, q_, qd_);
    factored_ = false;
    solve_projection_orthonormal(t);
    return;
  }
  if (!factored_) factor_for_projection(t);
  factored_ = false;
  REFDYN_FIXED_DISPATCH(solve_projection_sized, (t))
  solve_projection_orthonormal(t);
}

void ReferenceDynamics::solve_projection_orthonormal(double t) {
  if (m_ == n_) {
    // No null space: q̈ = A⁻¹ rhs, i.e. q̈_dc = K_dc⁻¹ rhs with the partition's inverse (no basis
    // enters, so its error is cond(A)·ε like any solve with A), and f plays no part.
    const int m = m_;
    const double* __restrict Ki = Kinv_.data();
    const double* __restrict rhs = rhs_.data();
    double* __restrict qdd = qdd_.data();
    for (int r = 0; r < m; ++r) {
      double sum = 0;
      for (int j = 0; j < m; ++j) sum += Ki[j * m + r] * rhs[j];
      qdd[dep_[r]] = sum;
    }
    return;
  }
  projected_force(opt_.paper_literal_forces, dQ_, qd_, F_, tmp_n_);  // f, projected by Zᵀ
  // q̈ and λ (Aᵀλ = f − M q̈) from one factorization.
  const bool spd = orth_.solve(ev_.A.data(), data_.M.data(), tmp_n_.data(), rhs_.data(), qdd_.data(), lambda_.data());
  if (!(orth_.row_condition() <= opt_.max_condition)) throw NumericalFailure(t, dependent_rows_message(t));
  if (!spd)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the reduced mass matrix Zᵀ M Z is not positive definite");
  if (opt_.paper_literal_forces && m_ > 0) {  // λ belongs to F − M q̈ = (f − M q̈) − (∂Q/∂q̇)ᵀq̇
    tmp_n_.noalias() = dQ_.transpose() * qd_;
    orth_.multipliers(tmp_n_.data(), tmp_m_.data());
    lambda_ -= tmp_m_;
  }
}

template <int N, int Mr>
void ReferenceDynamics::solve_projection_sized(double t) {
  static_assert(N > 0, "sizes known at run time take solve_projection_orthonormal");
  const int n = N, m = Mr, k = n - m;
  projected_force(opt_.paper_literal_forces, dQ_, qd_, F_, tmp_n_);  // f, projected below by Nᵀ
  // The stacked system [Nᵀ M; A] q̈ = [Nᵀ F; rhs] is solved by the null-space method, which
  // gives the same q̈ with a (n−m)×(n−m) SPD solve instead of an n×n LU:
  //   particular solution  q̈_p: q̈_p,ic = 0, q̈_p,dc = K_dc⁻¹ rhs        (A q̈_p = rhs)
  //   q̈ = q̈_p + N u,   (Nᵀ M N) u = Nᵀ (F − M q̈_p).
  const int* __restrict dep = dep_.data();
  const int* __restrict ind = ind_.data();
  const double* __restrict Mp = data_.M.data();  // n × n, column-major
  const double* __restrict G = G_.data();        // m × k
  const double* __restrict Ki = Kinv_.data();
  const double* __restrict rhs = rhs_.data();
  double* __restrict f = tmp_n_.data();
  double* __restrict qdd = qdd_.data();
  for (int i = 0; i < n; ++i) qdd[i] = 0.0;
  for (int r = 0; r < m; ++r) {
    double sum = 0;
    for (int j = 0; j < m; ++j) sum += Ki[j * m + r] * rhs[j];
    qdd[dep[r]] = sum;
  }
  for (int r = 0; r < m; ++r) {  // F − M q̈_p
    const double a = qdd[dep[r]];
    const double* __restrict col = Mp + static_cast<size_t>(dep[r]) * n;
    for (int i = 0; i < n; ++i) f[i] -= a * col[i];
  }
  // MN = M N: column c = M e_ind[c] + Σ_r G(r, c) M e_dep[r].
  double* __restrict MN = MN_.data();  // n × k
  for (int c = 0; c < k; ++c) {
    double* __restrict out = MN + static_cast<size_t>(c) * n;
    const double* __restrict col = Mp + static_cast<size_t>(ind[c]) * n;
    for (int i = 0; i < n; ++i) out[i] = col[i];
    for (int r = 0; r < m; ++r) {
      const double g = G[c * m + r];
      const double* __restrict d = Mp + static_cast<size_t>(dep[r]) * n;
      for (int i = 0; i < n; ++i) out[i] += g * d[i];
    }
  }
  // Nᵀ (M N) and Nᵀ (F − M q̈_p): row c of Nᵀ = e_ind[c]ᵀ + Σ_r G(r, c) e_dep[r]ᵀ.
  double* NMN = NMN_.data();  // k × k; NMN, rk also reach the LLT through the members: no restrict
  double* rk = rk_.data();
  for (int c = 0; c < k; ++c) {
    for (int c2 = 0; c2 < k; ++c2) {
      const double* __restrict col = MN + static_cast<size_t>(c2) * n;
      double v = col[ind[c]];
      for (int r = 0; r < m; ++r) v += G[c * m + r] * col[dep[r]];
      NMN[c2 * k + c] = v;
    }
    double v = f[ind[c]];
    for (int r = 0; r < m; ++r) v += G[c * m + r] * f[dep[r]];
    rk[c] = v;
  }
  if (k > 0) {
    solve_reduced_mass(t, k);
    for (int c = 0; c < k; ++c) {
      qdd[ind[c]] += rk[c];
      for (int r = 0; r < m; ++r) qdd[dep[r]] += G[c * m + r] * rk[c];
    }
  }
}

namespace {
enum class KktStatus { Ok, MassNotPositiveDefinite, RowsDependent };

/// u = M⁻¹F, Y = M⁻¹Aᵀ, S = A Y, λ = S⁻¹(A u − rhs), q̈ = u − Y λ, on Eigen objects of fixed or
/// dynamic size (one source for both; the caller supplies the factorizations and workspaces).
KktStatus kkt_solve(const auto& M, const auto& A, const auto& F, const auto& rhs, auto& llt_n, auto& llt_m,
                    auto& Y, auto& S, auto& tmp, auto& qdd, auto& lambda) {
  llt_n.compute(M);
  if (llt_n.info() != Eigen::Success) return KktStatus::MassNotPositiveDefinite;
  qdd = F;
  llt_n.solveInPlace(qdd);
  if (A.rows() == 0) return KktStatus::Ok;
  Y = A.transpose();
  llt_n.solveInPlace(Y);
  S.noalias() = A.lazyProduct(Y);
  llt_m.compute(S);
  if (llt_m.info() != Eigen::Success) return KktStatus::RowsDependent;
  tmp.noalias() = A.lazyProduct(qdd);
  tmp -= rhs;
  lambda = tmp;
  llt_m.solveInPlace(lambda);
  qdd.noalias() -= Y.lazyProduct(lambda);
  return KktStatus::Ok;
}
}  // namespace

void ReferenceDynamics::solve_lagrange(double t) { REFDYN_SIZED_DISPATCH(solve_lagrange_sized, (t)) }

template <int N, int Mr>
void ReferenceDynamics::solve_lagrange_sized(double t) {
  KktStatus status;
  if constexpr (N > 0) {  // fixed sizes: factorizations and workspaces on the stack
    using MatN = Eigen::Matrix<double, N, N>;
    using MatM = Eigen::Matrix<double, Mr, Mr>;
    const Eigen::Map<const MatN> M(data_.M.data());
    const Eigen::Map<const Eigen::Matrix<double, Mr, N>> A(ev_.A.data());
    const Eigen::Map<const Eigen::Matrix<double, N, 1>> F(F_.data());
    const Eigen::Map<const Eigen::Matrix<double, Mr, 1>> rhs(rhs_.data());
    Eigen::Map<Eigen::Matrix<double, N, 1>> qdd(qdd_.data());
    Eigen::Map<Eigen::Matrix<double, Mr, 1>> lambda(lambda_.data());
    Eigen::LLT<MatN> llt_n;
    Eigen::LLT<MatM> llt_m;
    Eigen::Matrix<double, N, Mr> Y;
    MatM S;
    Eigen::Matrix<double, Mr, 1> tmp;
    status = kkt_solve(M, A, F, rhs, llt_n, llt_m, Y, S, tmp, qdd, lambda);
  } else {
    status = kkt_solve(data_.M, ev_.A, F_, rhs_, data_.llt, llt_m_, Y_, Smm_, tmp_m_, qdd_, lambda_);
  }
  if (status == KktStatus::MassNotPositiveDefinite)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite");
  if (status == KktStatus::RowsDependent)
    throw NumericalFailure(t, "at t = " + fmt(t) +
                                  " s the constraint rows are linearly dependent (A M⁻¹ Aᵀ is singular); "
                                  "hint: remove redundant constraints");
}

void ReferenceDynamics::solve_lagrange_aba(double t) {
  // u = M⁻¹F with F = Q − (c + g): ABA with τ = Q. Y = M⁻¹Aᵀ column by column with its
  // factorization; S = A Y, λ = S⁻¹(A u − rhs), q̈ = u − Y λ (as kkt_solve).
  if (unchecked::aba(model_, data_, q_, qd_, Q_, qdd_) >= 0)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite");
  for (int r = 0; r < m_; ++r) {
    for (int i = 0; i < n_; ++i) tmp_n_[i] = ev_.A(r, i);
    unchecked::aba_solve(model_, data_, tmp_n_.data(), Y_.col(r).data());
  }
  Smm_.noalias() = ev_.A.lazyProduct(Y_);
  llt_m_.compute(Smm_);
  if (llt_m_.info() != Eigen::Success)
    throw NumericalFailure(t, "at t = " + fmt(t) +
                                  " s the constraint rows are linearly dependent (A M⁻¹ Aᵀ is singular); "
                                  "hint: remove redundant constraints");
  tmp_m_.noalias() = ev_.A.lazyProduct(qdd_);
  tmp_m_ -= rhs_;
  lambda_ = tmp_m_;
  llt_m_.solveInPlace(lambda_);
  qdd_.noalias() -= Y_.lazyProduct(lambda_);
}

}  // namespace refdyn
