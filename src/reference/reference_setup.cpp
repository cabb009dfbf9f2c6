// ReferenceDynamics' setup (reference_dynamics.hpp): options, construction, the state layout,
// the partition (given or chosen by the best-conditioned K_dc) and the consistent initial state.
// The evaluation itself (derivative, the solves) is in reference_dynamics.cpp.
#include "refdyn/reference/reference_dynamics.hpp"

#include "refdyn/common/text.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

namespace refdyn {

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
  orth_ = OrthonormalNullSpaceSolve(n_, m_);
  orthonormal_ = !projection_uses_partition(n_, m_);
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

std::string ReferenceDynamics::dependent_rows_message(double t) const {
  std::ostringstream os;
  const double c = orth_.row_condition();
  os << "at t = " << t << " s the constraint rows [";
  for (int r = 0; r < m_; ++r) os << (r ? ", " : "") << constraints_.row_name(r);
  os << "] are dependent or nearly so: the triangular factor of their Jacobian has condition estimate "
     << (std::isfinite(c) ? fmt(c) : std::string("inf")) << " > max_condition " << fmt(opt_.max_condition)
     << " (hint: remove redundant constraints or start away from this configuration)";
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
    cond_current_ = true;
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
