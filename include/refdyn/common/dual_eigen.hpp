#pragma once
/// Dual numbers (dual.hpp) as an Eigen scalar, as Ceres does for its Jet: Eigen's containers,
/// maps and arithmetic work on Eigen::Matrix<ad::Dual<N>, …>, so a law written over a scalar S
/// with Eigen expressions instantiates for double and for dual numbers alike (the controllers,
/// simulate/controllers.hpp). Comparisons compare the values (pivoting and branches follow the
/// value; the derivative is that of the branch taken). Linear solves over duals are not done by
/// Eigen's decompositions here but by solve_square (one factorization of the values, the
/// derivative parts by the same factorization: x' = A⁻¹(b' − A' x)).
#include "refdyn/common/dual.hpp"

#include <Eigen/Core>
#include <Eigen/LU>

#include <limits>

namespace refdyn::ad {
template <int N> bool operator<(const Dual<N>& a, const Dual<N>& b) { return a.v < b.v; }
template <int N> bool operator>(const Dual<N>& a, const Dual<N>& b) { return a.v > b.v; }
template <int N> bool operator<=(const Dual<N>& a, const Dual<N>& b) { return a.v <= b.v; }
template <int N> bool operator>=(const Dual<N>& a, const Dual<N>& b) { return a.v >= b.v; }
/// Equal values and derivatives.
template <int N> bool operator==(const Dual<N>& a, const Dual<N>& b) { return a.v == b.v && a.d == b.d; }
template <int N> bool operator!=(const Dual<N>& a, const Dual<N>& b) { return !(a == b); }
/// The value part: of a double, itself.
inline double value(double x) { return x; }
template <int N> double value(const Dual<N>& x) { return x.v; }
}  // namespace refdyn::ad

namespace Eigen {
template <int N>
struct NumTraits<refdyn::ad::Dual<N>> : GenericNumTraits<double> {
  using Real = refdyn::ad::Dual<N>;
  using NonInteger = Real;
  using Nested = Real;
  using Literal = Real;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = 1,
    AddCost = N + 1,
    MulCost = 2 * N + 1
  };
  static Real epsilon() { return Real(std::numeric_limits<double>::epsilon()); }
  static Real dummy_precision() { return Real(1e-12); }
  static Real highest() { return Real(std::numeric_limits<double>::max()); }
  static Real lowest() { return Real(std::numeric_limits<double>::lowest()); }
  static int digits10() { return std::numeric_limits<double>::digits10; }
};
template <int N, typename Op>
struct ScalarBinaryOpTraits<refdyn::ad::Dual<N>, double, Op> {
  using ReturnType = refdyn::ad::Dual<N>;
};
template <int N, typename Op>
struct ScalarBinaryOpTraits<double, refdyn::ad::Dual<N>, Op> {
  using ReturnType = refdyn::ad::Dual<N>;
};
}  // namespace Eigen

namespace refdyn::ad {

template <class S>
using MatrixX = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
template <class S>
using VectorX = Eigen::Matrix<S, Eigen::Dynamic, 1>;

/// x = A⁻¹ b for a square A (LU with partial pivoting of the values). Returns false when A is
/// singular to working precision (reciprocal condition below 1e-13; x is then left unset).
/// Out of line (src/common/dual_eigen.cpp): the LU's instantiation would cost every includer
/// ~3 CPU-seconds.
bool solve_square(const MatrixX<double>& A, const MatrixX<double>& B, MatrixX<double>& X);
/// The same over dual numbers: the values by one factorization, each derivative direction k by
/// the same factorization, X_k = A⁻¹(B_k − A_k X) (exact: the derivative of A⁻¹B).
template <int N>
bool solve_square(const MatrixX<Dual<N>>& A, const MatrixX<Dual<N>>& B, MatrixX<Dual<N>>& X) {
  const Eigen::Index n = A.rows(), c = B.cols();
  X.resize(n, c);
  if (n == 0) return true;
  const MatrixX<double> Av = A.unaryExpr([](const Dual<N>& x) { return x.v; });
  Eigen::PartialPivLU<MatrixX<double>> lu(Av);
  if (!(lu.rcond() > 1e-13)) return false;
  const MatrixX<double> Xv = lu.solve(B.unaryExpr([](const Dual<N>& x) { return x.v; }).eval());
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < c; ++j) X(i, j) = Dual<N>(Xv(i, j));
  for (int k = 0; k < N; ++k) {
    const MatrixX<double> Ak = A.unaryExpr([k](const Dual<N>& x) { return x.d[k]; });
    const MatrixX<double> Bk = B.unaryExpr([k](const Dual<N>& x) { return x.d[k]; });
    if (Ak.isZero(0.0) && Bk.isZero(0.0)) continue;
    const MatrixX<double> Xk = lu.solve((Bk - Ak * Xv).eval());
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < c; ++j) X(i, j).d[k] = Xk(i, j);
  }
  return true;
}

}  // namespace refdyn::ad
