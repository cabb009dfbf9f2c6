// The one compiled copy of Eigen's dense decompositions over MatrixXd
// (include/refdyn/common/detail/eigen_instances.hpp says why).
#include "refdyn/common/detail/eigen_instances.hpp"

namespace Eigen {
template class JacobiSVD<MatrixXd, ColPivHouseholderQRPreconditioner>;
template class PartialPivLU<MatrixXd>;
template class FullPivLU<MatrixXd>;
template class HouseholderQR<MatrixXd>;
template class ColPivHouseholderQR<MatrixXd>;
template class CompleteOrthogonalDecomposition<MatrixXd>;
template class LLT<MatrixXd, Lower>;
template class LDLT<MatrixXd, Lower>;
template class SelfAdjointEigenSolver<MatrixXd>;
template class EigenSolver<MatrixXd>;
}  // namespace Eigen
