#pragma once
/// Eigen's dense decompositions over MatrixXd, compiled once (src/common/eigen_instances.cpp)
/// instead of in every translation unit that factors a dynamic matrix.
///
/// Why: JacobiSVD, the LU and QR factorizations, LLT/LDLT and the eigen-solvers are large
/// templates; each source file that used one instantiated and optimized its own copy (the
/// backend's time in src/simulate/actuation.cpp went 49 → 31 CPU-s with these declarations;
/// docs/testing.md, "CI time"). An `extern template` declaration only tells the compiler that the
/// non-inline members are defined elsewhere: results are the same functions compiled with the
/// same flags (the library's), so numbers do not change. A file that does not include this header
/// instantiates its own copy, which is equally correct.
///
/// Only MatrixXd: the dual-number instantiations stay where they are used (their scalar sizes
/// differ per file).

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

namespace Eigen {
extern template class JacobiSVD<MatrixXd, ColPivHouseholderQRPreconditioner>;
extern template class PartialPivLU<MatrixXd>;
extern template class FullPivLU<MatrixXd>;
extern template class HouseholderQR<MatrixXd>;
extern template class ColPivHouseholderQR<MatrixXd>;
extern template class CompleteOrthogonalDecomposition<MatrixXd>;
extern template class LLT<MatrixXd, Lower>;
extern template class LDLT<MatrixXd, Lower>;
extern template class SelfAdjointEigenSolver<MatrixXd>;
extern template class EigenSolver<MatrixXd>;
}  // namespace Eigen
