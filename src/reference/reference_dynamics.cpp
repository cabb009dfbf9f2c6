#include "refdyn/reference/reference_dynamics.hpp"

#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/text.hpp"

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

void ReferenceDynamicsOptions::validate() const {
  auto need = [](bool ok, const char* what, const char* expected, double got) {
    if (!ok) throw Error(expected_got(std::string("reference dynamics option ") + what, expected, fmt(got)));
  };
  need(std::isfinite(alpha) && alpha >= 0, "alpha", "a finite value >= 0 [1/s]", alpha);
  need(std::isfinite(beta) && beta >= 0, "beta", "a finite value >= 0 [1/s]", beta);
  need(std::isfinite(beta_first_order) && beta_first_order >= 0, "beta_first_order", "a finite value >= 0 [1/s]",
       beta_first_order);
  need(max_condition > 1, "max_condition", "a value > 1", max_condition);
  need(std::isfinite(projection_tolerance) && projection_tolerance > 0, "projection_tolerance", "a finite value > 0",
       projection_tolerance);
  need(projection_max_iterations >= 1, "projection_max_iterations", "a count >= 1", projection_max_iterations);
}

ReferenceDynamics::ReferenceDynamics(const Model& model, const ForceSet& forces, const ConstraintSet& constraints,
                                     ReferenceDynamicsOptions options)
    : model_(model), forces_(forces), constraints_(constraints), opt_(std::move(options)), n_(model.nq),
      m_(constraints.rows()), data_(model), ev_(model, constraints) {
  opt_.validate();
  if (opt_.stabilization == Stabilization::Projection) opt_.alpha = opt_.beta = opt_.beta_first_order = 0.0;
  if (opt_.solver == ReferenceSolver::Automatic) opt_.solver = automatic_reference_solver(n_, m_);
  aba_ = m_ == 0 && constraints.points().empty() && forward_dynamics_uses_aba(n_);
  aba_lagrange_ = m_ > 0 && opt_.solver == ReferenceSolver::Lagrange && n_ >= kAbaLagrangeFrom;
  for (int r = 0; r < constraints.rows(); ++r) {
    first_order_row_.push_back(constraints.row_first_order(r));
    acceleration_row_.push_back(constraints.row_order(r) == 2);
    has_acceleration_rows_ = has_acceleration_rows_ || acceleration_row_.back();
  }
  if (m_ > n_)
    throw Error(expected_got("number of constraint rows", "at most the number of coordinates (" + std::to_string(n_) + ")",
                             std::to_string(m_), "remove redundant constraints"));
  const int nz = forces.num_states();
  q_.setZero(n_);
  qd_.setZero(n_);
  Q_.setZero(n_);
  F_.setZero(n_);
  rhs_.setZero(m_);
  qdd_.setZero(n_);
  lambda_.setZero(m_);
  Qc_.setZero(n_);
  zdot_.setZero(std::max(nz, 1));
  tmp_n_.setZero(n_);
  tmp_m_.setZero(m_);
  dQ_.setZero(n_, n_);
  Kdc_.setZero(m_, m_);
  Kic_.setZero(m_, n_ - m_);
  Kinv_.setZero(m_, m_);
  G_.setZero(m_, n_ - m_);
  Y_.setZero(n_, m_);
  MN_.setZero(n_, n_ - m_);
  NMN_.setZero(n_ - m_, n_ - m_);
  rk_.setZero(n_ - m_);
  Smm_.setZero(m_, m_);
  W_.setZero(n_, n_);
  ws_.setZero(std::max(n_, 1));
  qrA_.setZero(n_, m_);
  tau_.setZero(std::max(m_, 1));
  lu_m_ = Eigen::PartialPivLU<Eigen::MatrixXd>(m_);
  // Storage sized once (no allocation later) by factoring identities: Eigen's LLT(Index)
  // constructor leaves its info flag uninitialised, which UBSan reports on the move-assignment.
  llt_k_.compute(Eigen::MatrixXd::Identity(n_ - m_, n_ - m_));
  llt_m_.compute(Eigen::MatrixXd::Identity(m_, m_));
  if (!opt_.independent.empty()) {
    std::vector<int> ind;
    for (const auto& name : opt_.independent) ind.push_back(model.joint_index(name));
    set_independent(ind);
  }
}

Eigen::VectorXd ReferenceDynamics::make_state(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const {
  model_.check_q(q);
  check_vector("qd", qd, n_);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(state_size());
  x.head(n_) = q;
  x.segment(n_, n_) = qd;
  return x;
}

void ReferenceDynamics::set_independent(const std::vector<int>& ind) {
  const int k = n_ - m_;
  if (static_cast<int>(ind.size()) != k) {
    std::string names;
    for (int i = 0; i < n_; ++i) names += (i ? ", " : "") + model_.joint_name[i];
    throw Error(expected_got("number of independent coordinates", std::to_string(k) + " (coordinates " +
                             std::to_string(n_) + " minus constraint rows " + std::to_string(m_) + ")",
                             std::to_string(ind.size()), "pick them among: " + names));
  }
  std::vector<bool> is_ind(n_, false);
  for (int i : ind) {
    if (i < 0 || i >= n_) throw Error(expected_got("independent coordinate index", "0 .. nq-1", std::to_string(i)));
    if (is_ind[i]) throw Error("independent coordinate '" + model_.joint_name[i] + "' is listed twice");
    is_ind[i] = true;
  }
  ind_ = ind;
  dep_.clear();
  for (int i = 0; i < n_; ++i)
    if (!is_ind[i]) dep_.push_back(i);
  partition_set_ = true;
}

#include "sized_dispatch.hpp"  // REFDYN_FIXED_DISPATCH, REFDYN_SIZED_DISPATCH (why: there)

bool ReferenceDynamics::factor_partition() { REFDYN_SIZED_DISPATCH(factor_partition_sized, ()) }

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

std::string ReferenceDynamics::partition_message(double t) const {
  std::ostringstream os;
  os << "at t = " << t << " s the velocity partition is singular or ill-conditioned: K_dc of constraints [";
  for (int r = 0; r < m_; ++r) os << (r ? ", " : "") << constraints_.row_name(r);
  os << "] over dependent coordinates [";
  for (size_t i = 0; i < dep_.size(); ++i) os << (i ? ", " : "") << model_.joint_name[dep_[i]];
  os << "] has condition number " << (std::isfinite(cond_) ? fmt(cond_) : std::string("inf")) << " > "
     << fmt(opt_.max_condition)
     << " (hint: choose other independent coordinates, enable automatic_partition, or use the Lagrange solver)";
  return os.str();
}

double ReferenceDynamics::choose_partition(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  model_.check_q(q);
  check_vector("qd", qd, n_);
  evaluate_constraints(model_, data_, constraints_, ev_, t, q, qd);
  if (m_ == 0) {
    std::vector<int> all(n_);
    std::iota(all.begin(), all.end(), 0);
    set_independent(all);
    cond_ = 1.0;
    return cond_;
  }
  // Count candidate sets C(n, m).
  double count = 1;
  for (int i = 0; i < m_; ++i) count = count * (n_ - i) / (i + 1);
  std::vector<int> best_dep;
  double best = std::numeric_limits<double>::infinity();
  const double sigma_max_A = Eigen::JacobiSVD<Eigen::MatrixXd>(ev_.A).singularValues()(0);
  if (count <= 500) {
    std::vector<bool> sel(n_, false);
    std::fill(sel.end() - m_, sel.end(), true);
    Eigen::MatrixXd K(m_, m_);
    do {
      std::vector<int> dep;
      for (int i = 0; i < n_; ++i)
        if (sel[i]) dep.push_back(i);
      for (int c = 0; c < m_; ++c) K.col(c) = ev_.A.col(dep[c]);
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(K);
      const auto& s = svd.singularValues();
      const double c = s(m_ - 1) > 0 ? sigma_max_A / s(m_ - 1) : std::numeric_limits<double>::infinity();
      if (c < best) {
        best = c;
        best_dep = dep;
      }
    } while (std::next_permutation(sel.begin(), sel.end()));
  } else {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(ev_.A);
    for (int i = 0; i < m_; ++i) best_dep.push_back(qr.colsPermutation().indices()[i]);
    std::sort(best_dep.begin(), best_dep.end());
    if (qr.rank() == m_) {
      Eigen::MatrixXd K(m_, m_);
      for (int c = 0; c < m_; ++c) K.col(c) = ev_.A.col(best_dep[c]);
      const auto sv = Eigen::JacobiSVD<Eigen::MatrixXd>(K).singularValues();
      best = sv(m_ - 1) > 0 ? sigma_max_A / sv(m_ - 1) : best;
    }
  }
  if (best_dep.size() != static_cast<size_t>(m_) || !std::isfinite(best)) {
    std::string rows;
    for (int r = 0; r < m_; ++r) rows += (r ? ", " : "") + constraints_.row_name(r);
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the constraint Jacobian of [" + rows +
                                  "] is rank-deficient: no choice of dependent coordinates gives a regular K_dc "
                                  "(hint: remove redundant constraints or start away from this configuration)");
  }
  std::vector<int> ind;
  for (int i = 0; i < n_; ++i)
    if (std::find(best_dep.begin(), best_dep.end(), i) == best_dep.end()) ind.push_back(i);
  set_independent(ind);
  factor_partition();
  return cond_;
}

// ẋ = [q̇; q̈; ż], stage by stage (each stage is a member below, in this order).
void ReferenceDynamics::derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  read_state(t, x, xdot);
  const double* z = forces_.num_states() ? x.data() + 2 * n_ : nullptr;
  if (aba_) {  // no constraint rows, a large model: q̈ = M⁻¹(Q − c − g) by the articulated-body algorithm
    unconstrained_aba(t, z);
    write_derivative(xdot);
    return;
  }
  bias_and_constraints(t);  // M and c + g in one sweep; Φ, Φ̇, A, γ reusing its body motions
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

// Q_c = M q̈ − F (or −Aᵀλ where M is not formed); projection: λ from the dependent rows,
// K_dcᵀ λ = (F − M q̈)_dc = −Q_c,dc.
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
  if (opt_.solver == ReferenceSolver::Projection && m > 0) {
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

ReferenceDynamics::Consistency ReferenceDynamics::make_consistent(double t, const Eigen::VectorXd& q0,
                                                                  const Eigen::VectorXd& qd0, double tol,
                                                                  int max_iterations) {
  model_.check_q(q0);
  check_vector("qd", qd0, n_);
  if (!partition_set_) choose_partition(t, q0, qd0);
  Consistency out;
  out.q = q0;
  out.qd = qd0;
  auto residuals = [&](const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
    evaluate_constraints(model_, data_, constraints_, ev_, t, q, qd);
    double r = 0;
    for (int i = 0; i < m_; ++i) r = std::max({r, std::abs(ev_.phi[i]), std::abs(ev_.phid[i])});
    return r;
  };
  out.residual_before = residuals(out.q, out.qd);
  std::vector<int> hol, state_rows;  // acceleration rows do not restrict (q, q̇)
  for (int r = 0; r < m_; ++r) {
    if (constraints_.row_order(r) == 0) hol.push_back(r);
    if (constraints_.row_order(r) <= 1) state_rows.push_back(r);
  }
  // Minimum-norm Newton steps on the dependent coordinates of x (q or q̇) until the residuals
  // `value` (Φ, or Φ̇ and c, which are A q̇ + b = 0 in q̇) of the given rows are below tol.
  auto newton = [&](const std::vector<int>& rows, const Eigen::VectorXd& value, Eigen::VectorXd& x, bool count) {
    for (int it = 0; it < max_iterations && !rows.empty(); ++it) {
      evaluate_constraints(model_, data_, constraints_, ev_, t, out.q, out.qd);
      Eigen::VectorXd r(rows.size());
      Eigen::MatrixXd K(rows.size(), dep_.size());
      for (size_t i = 0; i < rows.size(); ++i) {
        r[i] = value[rows[i]];
        for (size_t c = 0; c < dep_.size(); ++c) K(i, c) = ev_.A(rows[i], dep_[c]);
      }
      if (count) out.iterations = it + 1;
      if (r.cwiseAbs().maxCoeff() <= tol) break;
      const Eigen::VectorXd step = K.completeOrthogonalDecomposition().solve(r);
      for (size_t c = 0; c < dep_.size(); ++c) x[dep_[c]] -= step[c];
    }
  };
  newton(hol, ev_.phi, out.q, true);          // position level: holonomic rows
  newton(state_rows, ev_.phid, out.qd, false);  // velocity level: position and velocity rows
  out.residual_after = residuals(out.q, out.qd);
  out.converged = out.residual_after <= std::max(tol, 1e3 * tol * (1 + out.residual_before)) ||
                  out.residual_after <= 1e-10;
  out.dq = out.q - q0;
  out.dqd = out.qd - qd0;
  return out;
}

}  // namespace refdyn
