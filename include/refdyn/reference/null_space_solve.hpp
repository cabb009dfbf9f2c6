#pragma once
/// The projection route's solve with an orthonormal basis of the constraints' null space
/// (reference_dynamics.hpp, "Null-space basis"): given M (n × n, SPD), the constraint Jacobian
/// A (m × n, full row rank), f and rhs, the q̈ with
///     A q̈ = rhs,   Zᵀ (M q̈ − f) = 0,
/// where the columns of Z are an orthonormal basis of the null space of A. That is the q̈ of the
/// KKT system [[M, Aᵀ], [A, 0]] [q̈; λ] = [f; rhs], and its rounding error is cond(M)·ε like the
/// KKT solve's (no K_dc⁻¹ of a partition enters).
///
/// Method. Householder QR Aᵀ = Q [R; 0], Q = H_0 ⋯ H_{m−1}, Z = the last k = n − m columns of Q;
/// with y = Qᵀ q̈ = [y1; y2]: Rᵀ y1 = rhs (so q̈_p = Q [y1; 0] satisfies the rows) and
/// (ZᵀMZ) y2 = Zᵀ (f − M q̈_p), an SPD solve. ZᵀMZ is formed by one of two routes,
/// the one with fewer flops for the sizes (common/crossovers.hpp, explicit_null_basis):
///   explicit basis — [q̈_p, Z] = Q [[y1, 0]; [0, I_k]] by the reflectors, then M [q̈_p, Z]
///                    (2n²k flops): cheaper when k is small next to m;
///   two-sided      — W = Qᵀ M Q by a symmetric rank-2 update per reflector (≈ 6n²m flops),
///                    W22 = ZᵀMZ, then q̈ = Q [y1; y2].
/// Speed. Every vector operation runs over whole columns padded with zeros to L rows (L = 8, 12,
/// 16, or n rounded up to a multiple of 8), on fixed-size Eigen maps for the first three: no
/// loop depends on the reflector's index, so each column operation is a few SIMD instructions.
/// All storage is sized by the constructor; solve() does not allocate. ZᵀMZ is factored as LDLᵀ
/// written out for k ≤ 16 (no square roots, one division per row: Eigen's dynamic LLT costs more
/// than its flops at those sizes), a single division for k = 1, Eigen's LLT above 16.
#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace refdyn {

class OrthonormalNullSpaceSolve {
 public:
  OrthonormalNullSpaceSolve() = default;
  /// Storage for n coordinates and m rows, 0 ≤ m ≤ n (Error otherwise).
  OrthonormalNullSpaceSolve(int n, int m);

  /// q̈ (n) from A (m × n), M (n × n), both column-major, f (n) and rhs (m), and, when `lambda` is
  /// given, the KKT system's multipliers λ (m): Aᵀλ = f − M q̈, from the same factorization (the
  /// two-sided route has (Qᵀ(f − M q̈))₁ = (Qᵀf)₁ − (QᵀMQ y)₁ at hand; the explicit one forms
  /// Q₁ = Q [I_m; 0] beside Z, m more columns through the same reflections). A must have full
  /// row rank: check row_condition() after the call (a zero R_jj makes q̈ not finite). Returns
  /// false, leaving q̈ and λ unspecified, when ZᵀMZ is not positive definite (M is not).
  bool solve(const double* A, const double* M, const double* f, const double* rhs, double* qdd,
             double* lambda = nullptr);

  /// max_j |R_jj| / min_j |R_jj| of the last solve's R (1 without rows; infinite when an R_jj is 0
  /// or not finite): a lower bound of cond₂(A), infinite or huge when the rows are dependent.
  double row_condition() const;

  /// After a solve() that returned true: λ (m) with Aᵀλ = g in the least-squares sense,
  /// λ = R⁻¹ (Qᵀ g)₁, from that solve's factorization of A (no second one). For a g that lies in
  /// the range of Aᵀ (up to rounding), such as a part of f − M q̈.
  void multipliers(const double* g, double* lambda);

  int rows() const { return m_; }
  int coordinates() const { return n_; }
  bool explicit_basis() const { return explicit_; }  ///< which route forms ZᵀMZ (above)
  int padded_rows() const { return L_; }             ///< L: the column length of the kernels
  static int padded_rows(int n);                     ///< 8, 12, 16, or n rounded up to 8

 private:
  template <int L>
  bool solve_padded(const double* A, const double* M, const double* f, const double* rhs, double* qdd,
                    double* lambda);
  void back_substitute(const double* t, double* lambda) const;  // R λ = t (m)
  template <int L>
  void multipliers_padded(const double* g, double* lambda);
  bool spd_solve();  // S y2 = u in place (S_: k × k, lower triangle row by row); false unless S is PD

  int n_ = 0, m_ = 0, k_ = 0, L_ = 8;
  bool explicit_ = false;
  Eigen::VectorXd V_;      // L × m: the reflectors v_j (zero above j, 1 at j, zero padding)
  Eigen::VectorXd R_;      // m × m, column-major: R of Aᵀ = Q [R; 0] (upper triangle)
  Eigen::VectorXd tau_;    // m: H_j = I − τ_j v_j v_jᵀ
  Eigen::VectorXd y1_;     // L: Rᵀ y1 = rhs in rows 0 … m−1
  Eigen::VectorXd rows_;   // L: 0, 1, …, L − 1 (the row index the column operations mask with)
  Eigen::VectorXd work_;   // explicit: [q̈_p, Z], M [q̈_p, Z], M, Q₁ (L × (k+1), L × (k+1), L × n, L × m); else W (L × n)
  Eigen::VectorXd f_, p_;  // L: f (or Qᵀf, then y); the rank-2 update's vector, then f − M q̈ for λ (multipliers(): Qᵀg)
  Eigen::VectorXd S_, u_;  // k × k (lower, row by row): ZᵀMZ and its factor; k: Zᵀ(f − M q̈_p), y2
  Eigen::MatrixXd big_;    // k × k for Eigen's LLT when k > 16
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

}  // namespace refdyn
