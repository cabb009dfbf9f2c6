// The orthonormal null-space solve of the projection route (null_space_solve.hpp: the method,
// its two ways of forming ZᵀMZ and why the columns are padded).
#include "refdyn/reference/null_space_solve.hpp"

#include "refdyn/common/crossovers.hpp"
#include "refdyn/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

namespace refdyn {

namespace {
// Column operations over L rows: fixed-size maps for L = 8, 12, 16 (L = 0: the length at run
// time). Columns hold zeros below row n (see solve()), so running over all L rows changes
// nothing else.
template <int L>
using Col = Eigen::Map<Eigen::Matrix<double, L == 0 ? Eigen::Dynamic : L, 1>>;
template <int L>
using ConstCol = Eigen::Map<const Eigen::Matrix<double, L == 0 ? Eigen::Dynamic : L, 1>>;
template <int L>
double dot(const double* a, const double* b, int len) {
  return ConstCol<L>(a, len).dot(ConstCol<L>(b, len));
}
template <int L>
void axpy(double* y, double a, const double* x, int len) {  // y += a x
  Col<L>(y, len) += a * ConstCol<L>(x, len);
}
// y ← H y = y − τ v (vᵀ y)
template <int L>
void reflect(double* y, double tau, const double* v, int len) {
  axpy<L>(y, -tau * dot<L>(v, y, len), v, len);
}
constexpr int kWrittenFactorMax = 16;  // larger ZᵀMZ: Eigen's LLT
// f(std::integral_constant<int, L>) for the column length L compiled with fixed sizes, else L = 0.
template <class F>
decltype(auto) with_length(int L, F&& f) {
  switch (L) {
    case 8: return f(std::integral_constant<int, 8>{});
    case 12: return f(std::integral_constant<int, 12>{});
    case 16: return f(std::integral_constant<int, 16>{});
    default: return f(std::integral_constant<int, 0>{});
  }
}
}  // namespace

int OrthonormalNullSpaceSolve::padded_rows(int n) { return n <= 8 ? 8 : n <= 12 ? 12 : n <= 16 ? 16 : (n + 7) / 8 * 8; }

OrthonormalNullSpaceSolve::OrthonormalNullSpaceSolve(int n, int m)
    : n_(n), m_(m), k_(n - m), L_(padded_rows(n)), explicit_(explicit_null_basis(n, m)) {
  if (n < 0 || m < 0 || m > n)
    throw Error("OrthonormalNullSpaceSolve: expected 0 <= m <= n, got n = " + std::to_string(n) +
                ", m = " + std::to_string(m));
  const int L = L_, k = k_;
  V_.setZero(static_cast<Eigen::Index>(L) * m);
  R_.setZero(static_cast<Eigen::Index>(m) * m);
  tau_.setZero(m);
  y1_.setZero(L);  // read as a whole column (rows ≥ m masked)
  rows_ = Eigen::VectorXd::LinSpaced(L, 0, L - 1);
  work_.setZero(static_cast<Eigen::Index>(L) * (explicit_ ? 2 * (k + 1) + n + m : n));
  f_.setZero(L);
  p_.setZero(L);
  S_.setZero(static_cast<Eigen::Index>(k) * k);
  u_.setZero(k);
  if (k > kWrittenFactorMax) {  // sized once: compute() then only copies
    big_.setZero(k, k);
    llt_.compute(Eigen::MatrixXd::Identity(k, k));
  }
}

bool OrthonormalNullSpaceSolve::solve(const double* A, const double* M, const double* f, const double* rhs,
                                      double* qdd, double* lambda) {
  return with_length(L_, [&](auto L) { return solve_padded<L()>(A, M, f, rhs, qdd, lambda); });
}

template <int Lc>
bool OrthonormalNullSpaceSolve::solve_padded(const double* A, const double* M, const double* f,
                                             const double* rhs, double* qdd, double* lambda) {
  const int n = n_, m = m_, k = k_, L = Lc > 0 ? Lc : L_;
  double* __restrict V = V_.data();
  double* __restrict R = R_.data();
  double* __restrict tau = tau_.data();
  double* __restrict y1 = y1_.data();
  double* __restrict S = S_.data();
  double* __restrict u = u_.data();
  double* __restrict fq = f_.data();
  // M and f into padded columns first (independent of the QR below, so they overlap its latency):
  // M into W (two-sided) or after the explicit route's two blocks of k + 1 columns.
  double* __restrict work = work_.data();
  {
    double* __restrict Mp = explicit_ ? work + static_cast<size_t>(2 * (k + 1)) * L : work;
    for (int c = 0; c < n; ++c)
      for (int i = 0; i < n; ++i) Mp[static_cast<size_t>(c) * L + i] = M[static_cast<size_t>(c) * n + i];
    for (int i = 0; i < n; ++i) fq[i] = f[i];
  }
  // Aᵀ = Q [R; 0]: column j of Aᵀ gives reflector j, which then acts on columns j+1 … m−1.
  for (int c = 0; c < m; ++c) {
    double* __restrict x = V + static_cast<size_t>(c) * L;
    for (int i = 0; i < n; ++i) x[i] = A[static_cast<size_t>(i) * m + c];
  }
  // Whole columns are written with one vector store and masked in registers (select on the row
  // index) rather than element by element: a vector load right after scalar stores into the
  // same column stalls (the stores cannot be forwarded to it).
  const auto row = ConstCol<Lc>(rows_.data(), L).array();  // 0, 1, …, L − 1
  for (int j = 0; j < m; ++j) {
    double* __restrict x = V + static_cast<size_t>(j) * L;
    for (int i = 0; i < j; ++i) R[static_cast<size_t>(j) * m + i] = x[i];  // column j of R above the diagonal
    const double alpha = x[j];
    const auto col = ConstCol<Lc>(x, L).array();
    const auto below = (row > double(j)).select(col, 0.0).matrix();  // rows j+1 … of column j
    const double tail = below.squaredNorm();
    if (!(tail > 0)) {  // already α e_j below the diagonal: H_j = I
      tau[j] = 0;
      R[static_cast<size_t>(j) * m + j] = alpha;
      Col<Lc>(x, L) = (row == double(j)).select(1.0, 0.0 * row).matrix();
      continue;
    }
    const double beta = alpha >= 0 ? -std::sqrt(alpha * alpha + tail) : std::sqrt(alpha * alpha + tail);
    tau[j] = (beta - alpha) / beta;
    const double s = 1.0 / (alpha - beta);
    Col<Lc>(x, L) = (row > double(j)).select(s * col, (row == double(j)).select(1.0, 0.0 * row)).matrix();  // v_j
    R[static_cast<size_t>(j) * m + j] = beta;
    for (int c = j + 1; c < m; ++c) reflect<Lc>(V + static_cast<size_t>(c) * L, tau[j], x, L);
  }
  for (int r = 0; r < m; ++r) {  // Rᵀ y1 = rhs
    double sum = rhs[r];
    for (int c = 0; c < r; ++c) sum -= R[static_cast<size_t>(r) * m + c] * y1[c];
    y1[r] = sum / R[static_cast<size_t>(r) * m + r];
  }
  if (explicit_) {
    // B = [q̈_p, Z] = Q [[y1, 0]; [0, I_k]], MB = M B, then ZᵀMZ = Zᵀ (MZ), Zᵀ (f − M q̈_p); for λ
    // also Q₁ = Q [I_m; 0] (H_j leaves e_i alone for i < j: v_j is zero above row j).
    double* __restrict B = work;
    double* __restrict MB = B + static_cast<size_t>(k + 1) * L;
    double* __restrict Mp = MB + static_cast<size_t>(k + 1) * L;
    double* __restrict Q1 = Mp + static_cast<size_t>(n) * L;
    Col<Lc>(B, L) = (row < double(m)).select(ConstCol<Lc>(y1, L).array(), 0.0).matrix();  // [y1; 0]
    for (int c = 0; c < k; ++c) Col<Lc>(B + static_cast<size_t>(c + 1) * L, L) = (row == double(m + c)).select(1.0, 0.0 * row).matrix();
    if (lambda)
      for (int i = 0; i < m; ++i) Col<Lc>(Q1 + static_cast<size_t>(i) * L, L) = (row == double(i)).select(1.0, 0.0 * row).matrix();
    for (int j = m - 1; j >= 0; --j) {
      if (tau[j] == 0) continue;
      const double* __restrict v = V + static_cast<size_t>(j) * L;
      for (int c = 0; c <= k; ++c) reflect<Lc>(B + static_cast<size_t>(c) * L, tau[j], v, L);
      if (lambda)
        for (int i = j; i < m; ++i) reflect<Lc>(Q1 + static_cast<size_t>(i) * L, tau[j], v, L);
    }
    for (int c = 0; c <= k; ++c) {
      double* __restrict out = MB + static_cast<size_t>(c) * L;
      const double* __restrict b = B + static_cast<size_t>(c) * L;
      Col<Lc>(out, L).setZero();
      for (int j = 0; j < n; ++j) axpy<Lc>(out, b[j], Mp + static_cast<size_t>(j) * L, L);
    }
    Col<Lc>(fq, L) -= ConstCol<Lc>(MB, L);  // f − M q̈_p
    for (int r = 0; r < k; ++r) {
      const double* __restrict z = B + static_cast<size_t>(r + 1) * L;
      for (int c = 0; c <= r; ++c) S[static_cast<size_t>(r) * k + c] = dot<Lc>(z, MB + static_cast<size_t>(c + 1) * L, L);
      u[r] = dot<Lc>(z, fq, L);
    }
  } else {
    // W = Qᵀ M Q: W ← H_j W H_j as W − v wᵀ − w vᵀ with p = τ W v, w = p − (τ vᵀp / 2) v; Qᵀ f.
    double* __restrict W = work;
    double* __restrict p = p_.data();
    for (int j = 0; j < m; ++j) {
      const double tj = tau[j];
      if (tj == 0) continue;
      const double* __restrict v = V + static_cast<size_t>(j) * L;
      Col<Lc>(p, L).setZero();
      for (int c = j; c < n; ++c) axpy<Lc>(p, tj * v[c], W + static_cast<size_t>(c) * L, L);
      axpy<Lc>(p, -0.5 * tj * dot<Lc>(v, p, L), v, L);
      for (int c = 0; c < n; ++c) {
        double* __restrict col = W + static_cast<size_t>(c) * L;
        axpy<Lc>(col, -p[c], v, L);
        if (c >= j) axpy<Lc>(col, -v[c], p, L);
      }
      reflect<Lc>(fq, tj, v, L);
    }
    for (int r = 0; r < k; ++r) {  // W22 = ZᵀMZ; (Qᵀf)_2 − W21 y1
      const double* __restrict row = W + m + r;  // W(m + r, c) = row[c L]
      for (int c = 0; c <= r; ++c) S[static_cast<size_t>(r) * k + c] = row[static_cast<size_t>(m + c) * L];
      double v = fq[m + r];
      for (int c = 0; c < m; ++c) v -= row[static_cast<size_t>(c) * L] * y1[c];
      u[r] = v;
    }
  }
  // The padding rows (below row n) are zero from the constructor and stay zero while the numbers
  // are finite (they only ever get x · 0). A NaN or Inf in the input leaves NaN there (NaN · 0),
  // which would poison every later call; it also makes ZᵀMZ fail or reaches q̈ (and its padding),
  // so after such a call the storage is cleared. (Writing the padding on every call instead costs
  // ~35 ns at 7 DOF: the vector loads that follow wait for those scalar stores.)
  const auto clear = [this] {
    V_.setZero();
    work_.setZero();
    f_.setZero();
    p_.setZero();
  };
  if (k > 0 && !spd_solve()) {
    clear();
    return false;
  }
  // λ: R λ = (Qᵀ(f − M q̈))₁, with g in p_ (scratch on both routes by now).
  if (lambda) {
    double* __restrict g = p_.data();
    if (explicit_) {  // g = (f − M q̈_p) − MZ y2; (Qᵀg)₁ = Q₁ᵀ g
      const double* __restrict MB = work + static_cast<size_t>(k + 1) * L;
      const double* __restrict Q1 = MB + static_cast<size_t>(k + 1 + n) * L;
      Col<Lc>(g, L) = ConstCol<Lc>(fq, L);
      for (int c = 0; c < k; ++c) axpy<Lc>(g, -u[c], MB + static_cast<size_t>(c + 1) * L, L);
      for (int i = 0; i < m; ++i) lambda[i] = dot<Lc>(Q1 + static_cast<size_t>(i) * L, g, L);
    } else {  // (Qᵀf)₁ − (W y)₁, y = [y1; y2]
      const double* __restrict W = work;
      Col<Lc>(g, L) = ConstCol<Lc>(fq, L);
      for (int c = 0; c < m; ++c) axpy<Lc>(g, -y1[c], W + static_cast<size_t>(c) * L, L);
      for (int c = 0; c < k; ++c) axpy<Lc>(g, -u[c], W + static_cast<size_t>(m + c) * L, L);
      for (int i = 0; i < m; ++i) lambda[i] = g[i];
    }
    back_substitute(lambda, lambda);
  }
  if (explicit_) {  // q̈ = q̈_p + Z y2
    const double* __restrict B = work;
    Col<Lc>(fq, L) = ConstCol<Lc>(B, L);
    for (int c = 0; c < k; ++c) axpy<Lc>(fq, u[c], B + static_cast<size_t>(c + 1) * L, L);
  } else {  // q̈ = Q [y1; y2]
    for (int r = 0; r < m; ++r) fq[r] = y1[r];
    for (int c = 0; c < k; ++c) fq[m + c] = u[c];
    for (int j = m - 1; j >= 0; --j)
      if (tau[j] != 0) reflect<Lc>(fq, tau[j], V + static_cast<size_t>(j) * L, L);
  }
  for (int i = 0; i < n; ++i) qdd[i] = fq[i];
  if (!ConstCol<Lc>(fq, L).allFinite()) clear();
  return true;
}

double OrthonormalNullSpaceSolve::row_condition() const {
  const int m = m_;
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (int j = 0; j < m; ++j) {
    const double a = std::abs(R_[static_cast<Eigen::Index>(j) * m + j]);
    if (!(a > 0) || !std::isfinite(a)) return std::numeric_limits<double>::infinity();
    lo = std::min(lo, a);
    hi = std::max(hi, a);
  }
  return m ? hi / lo : 1.0;
}

void OrthonormalNullSpaceSolve::multipliers(const double* g, double* lambda) {
  with_length(L_, [&](auto L) { multipliers_padded<L()>(g, lambda); });
}

template <int Lc>
void OrthonormalNullSpaceSolve::multipliers_padded(const double* g, double* lambda) {
  const int n = n_, m = m_, L = Lc > 0 ? Lc : L_;
  const double* __restrict V = V_.data();
  // w = Qᵀ g = H_{m−1} ⋯ H_0 g, in registers for the fixed column lengths (a column in memory
  // would be stored and reloaded by every reflection, in series); in p_ (scratch here) above 16.
  using W = std::conditional_t<Lc == 0, Eigen::Map<Eigen::VectorXd>, Eigen::Matrix<double, Lc, 1>>;
  W w = [&] {
    if constexpr (Lc == 0) return W(p_.data(), L);
    else return W();
  }();
  w.setZero();
  for (int i = 0; i < n; ++i) w[i] = g[i];
  for (int j = 0; j < m; ++j)
    if (tau_[j] != 0) {
      const auto v = ConstCol<Lc>(V + static_cast<size_t>(j) * L, L);
      w -= (tau_[j] * v.dot(w)) * v;
    }
  back_substitute(w.data(), lambda);
}

// R λ = t (t may be λ itself). The reciprocals of R's diagonal do not depend on t, so up to 16
// rows they are taken first and only multiplications stay on the chain from one λ_r to the next.
void OrthonormalNullSpaceSolve::back_substitute(const double* t, double* lambda) const {
  const int m = m_;
  const double* __restrict R = R_.data();
  double inv[kWrittenFactorMax];
  const bool reciprocals = m <= kWrittenFactorMax;
  if (reciprocals)
    for (int r = 0; r < m; ++r) inv[r] = 1.0 / R[static_cast<size_t>(r) * m + r];
  for (int r = m - 1; r >= 0; --r) {
    double sum = t[r];
    for (int c = r + 1; c < m; ++c) sum -= R[static_cast<size_t>(c) * m + r] * lambda[c];
    lambda[r] = reciprocals ? sum * inv[r] : sum / R[static_cast<size_t>(r) * m + r];
  }
}

// S y2 = u in place for the SPD S_ (k × k, lower triangle row by row: S(r, c) = S[r k + c], c ≤ r).
bool OrthonormalNullSpaceSolve::spd_solve() {
  const int k = k_;
  double* __restrict S = S_.data();
  double* __restrict u = u_.data();
  if (k == 1) {  // one division (as the partitioned kernels do)
    if (!(S[0] > 0)) return false;
    u[0] /= S[0];
    return true;
  }
  if (k > kWrittenFactorMax) {
    for (int r = 0; r < k; ++r)
      for (int c = 0; c <= r; ++c) big_(r, c) = S[static_cast<size_t>(r) * k + c];
    llt_.compute(big_);  // reads the lower triangle
    if (llt_.info() != Eigen::Success) return false;
    llt_.solveInPlace(u_);
    return true;
  }
  // S = 𝓛 D 𝓛ᵀ row by row (𝓛 unit lower, in place below the diagonal; D's reciprocals kept): no
  // square roots and one division per row, off the chain of dependent operations. 𝓛 is stored
  // scaled, S(r, c) ← 𝓛(r, c) D(c) while row r is formed, then divided by D(c) once.
  double dinv[kWrittenFactorMax];
  for (int r = 0; r < k; ++r) {
    double* __restrict Sr = S + static_cast<size_t>(r) * k;
    for (int c = 0; c < r; ++c) {  // Sr[c] = 𝓛(r, c) D(c) = S(r, c) − Σ_j 𝓛(r, j) D(j) 𝓛(c, j)
      const double* __restrict Sc = S + static_cast<size_t>(c) * k;
      double s = Sr[c];
      for (int j = 0; j < c; ++j) s -= Sr[j] * Sc[j];
      Sr[c] = s;
    }
    double d = Sr[r];
    for (int c = 0; c < r; ++c) {  // D(r) = S(r, r) − Σ_c 𝓛(r, c)² D(c); then 𝓛(r, c) = Sr[c] / D(c)
      const double l = Sr[c] * dinv[c];
      d -= l * Sr[c];
      Sr[c] = l;
    }
    if (!(d > 0)) return false;
    dinv[r] = 1.0 / d;
  }
  for (int r = 0; r < k; ++r) {  // 𝓛 w = u
    double s = u[r];
    for (int j = 0; j < r; ++j) s -= S[static_cast<size_t>(r) * k + j] * u[j];
    u[r] = s;
  }
  for (int r = k - 1; r >= 0; --r) {  // 𝓛ᵀ y2 = D⁻¹ w
    double s = u[r] * dinv[r];
    for (int j = r + 1; j < k; ++j) s -= S[static_cast<size_t>(j) * k + r] * u[j];
    u[r] = s;
  }
  return true;
}

}  // namespace refdyn
