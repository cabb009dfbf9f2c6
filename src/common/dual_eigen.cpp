// The double overload of ad::solve_square (include/refdyn/common/dual_eigen.hpp), out of line.
#include "refdyn/common/dual_eigen.hpp"

#include <Eigen/LU>

namespace refdyn::ad {

bool solve_square(const MatrixX<double>& A, const MatrixX<double>& B, MatrixX<double>& X) {
  if (A.rows() == 0) {
    X.resize(0, B.cols());
    return true;
  }
  Eigen::PartialPivLU<MatrixX<double>> lu(A);
  if (!(lu.rcond() > 1e-13)) return false;
  X = lu.solve(B);
  return true;
}

}  // namespace refdyn::ad
