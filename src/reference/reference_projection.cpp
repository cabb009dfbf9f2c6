// ReferenceDynamics::project_state: drift-free stabilization by a mass-weighted least-change
// projection of (q, q̇) onto the constraints after each accepted step (reference_dynamics.hpp).
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <sstream>

namespace refdyn {

const char* to_string(Stabilization s) {
  switch (s) {
    case Stabilization::Baumgarte: return "baumgarte";
    case Stabilization::Projection: return "projection";
    case Stabilization::Both: return "both";
  }
  return "?";
}

namespace {

/// max |r_k| over the listed rows of v.
double worst(const Eigen::VectorXd& v, const std::vector<int>& rows) {
  double w = 0;
  for (int r : rows) w = std::max(w, std::abs(v[r]));
  return w;
}

}  // namespace

ReferenceDynamics::StateProjection ReferenceDynamics::project_state(double t, Eigen::VectorXd& x) {
  check_size("x", state_size(), x.size(), "x = [q; qd; z]");
  const int n = n_;
  std::vector<int> position_rows, velocity_rows;  // holonomic; holonomic and first order
  for (int r = 0; r < m_; ++r) {
    const int order = constraints_.row_order(r);
    if (order == 0) position_rows.push_back(r);
    if (order <= 1) velocity_rows.push_back(r);
  }
  if (velocity_rows.empty())
    throw Error("stabilization by projection needs position or velocity constraints; this problem has none (hint: "
                "stabilization: baumgarte)");
  Eigen::VectorXd q = x.head(n), qd = x.segment(n, n);
  StateProjection out;
  const double tol = opt_.projection_tolerance;
  // Residuals of one level: Φ on position rows, or Φ̇ (holonomic) and c (first order).
  Eigen::VectorXd r;
  Eigen::MatrixXd A, MinvAt, S;
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  auto level = [&](const std::vector<int>& rows, bool positions) {
    const int k = static_cast<int>(rows.size());
    if (k == 0) return;
    r.resize(k);
    A.resize(k, n);
    for (int it = 0;; ++it) {
      evaluate_constraints(model_, data_, constraints_, ev_, t, q, qd);
      for (int i = 0; i < k; ++i) {
        const int row = rows[i];
        r[i] = positions || constraints_.row_order(row) == 1 ? ev_.phi[row] : ev_.phid[row];
        A.row(i) = ev_.A.row(row);
      }
      const double res = r.cwiseAbs().maxCoeff();
      if (it == 0) out.residual_before = std::max(out.residual_before, res);
      if (!(res > tol)) {
        if (std::isfinite(res)) return;
      }
      if (it == opt_.projection_max_iterations || !std::isfinite(res)) {
        std::ostringstream os;
        os << "at t = " << fmt(t) << " s the projection onto the constraints did not converge: after " << it
           << " Newton iterations the " << (positions ? "position" : "velocity") << " residual is " << fmt(res)
           << " > projection tolerance " << fmt(tol) << " (rows [";
        for (int i = 0; i < k; ++i) os << (i ? ", " : "") << constraints_.row_name(rows[i]);
        os << "]; hint: a smaller step, a larger projection tolerance, or stabilization: both)";
        throw NumericalFailure(t, os.str());
      }
      unchecked::crba(model_, data_, q);
      llt.compute(data_.M);
      MinvAt = llt.solve(A.transpose());
      S.noalias() = A * MinvAt;
      lu.compute(S);
      if (!(std::abs(lu.determinant()) > 0))
        throw NumericalFailure(t, "at t = " + fmt(t) + " s the projection onto the constraints is singular (A M^-1 A^T "
                                  "has no inverse: redundant constraints or a singular configuration)");
      const Eigen::VectorXd step = -MinvAt * lu.solve(r);
      (positions ? q : qd) += step;
      double& size = positions ? out.dq : out.dqd;
      size = std::max(size, (positions ? (q - x.head(n)) : (qd - x.segment(n, n))).cwiseAbs().maxCoeff());
      ++out.iterations;
    }
  };
  level(position_rows, true);
  level(velocity_rows, false);
  evaluate_constraints(model_, data_, constraints_, ev_, t, q, qd);
  out.residual_after = std::max(worst(ev_.phi, position_rows), 0.0);
  for (int row : velocity_rows)
    out.residual_after = std::max(out.residual_after, std::abs(constraints_.row_order(row) == 1 ? ev_.phi[row] : ev_.phid[row]));
  x.head(n) = q;
  x.segment(n, n) = qd;
  return out;
}

}  // namespace refdyn
