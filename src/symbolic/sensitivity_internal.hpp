#pragma once
// Private to src/symbolic/sensitivity*.cpp: the symbolic forms of a plan's equations compiled
// into expression tapes with their gradients (sensitivity_tapes.cpp), the evaluator that solves
// the KKT system along directions, and the time law's derivatives in the chosen parameters. The
// propagation through the plan's RK4 steps is sensitivity.cpp (its header comment: the method).
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/symbolic_form.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn::sensitivity_detail {

/// The compiled tapes of one problem's structure for one set of chosen parameters.
struct Tapes {
  int n = 0, m = 0, nz = 0;
  int o_q = 0, o_qd = 0, o_z = 0, o_qdd = 0, o_lam = 0, o_p = 0, nv = 0;
  std::vector<std::string> pvars;  ///< parameter variables (the chosen ones and those made from them)
  std::vector<Expression> R, Zd, T, Phi, Phid;  ///< R: R₁ (n) then R₂ (m)
};

/// Total derivatives of every scenario parameter with respect to the chosen ones, through the
/// definitions in order (a chosen parameter's own definition is cut: it is the variable).
std::map<std::string, Eigen::RowVectorXd> parameter_derivatives(const Problem& problem,
                                                               const std::vector<std::string>& chosen);

/// d(text)/dp for a number written in the scenario (initial values, t1): "" is a constant.
Eigen::RowVectorXd text_derivative(const Problem& problem, const std::string& text,
                                   const std::map<std::string, Eigen::RowVectorXd>& D, int np);

/// The texts of R₁, R₂, ż, τ, Φ, Φ̇ with the parameters as symbols, and the values of the
/// parameters that stay constants.
struct Texts {
  std::vector<std::string> R, Zd, T, Phi, Phid;
  std::vector<std::string> symbols;          ///< the parameters the texts name
  std::map<std::string, double> values;      ///< their values, and the gains
  std::string key() const {
    std::string k;
    for (const auto* v : {&R, &Zd, &T, &Phi, &Phid})
      for (const auto& s : *v) k += s + ";";
    for (const auto& [name, value] : values) k += name + "=" + symbolic_number(value) + ";";
    return k;
  }
};

Texts symbolic_texts(const Problem& problem);

/// Compiled tapes, cached by their texts (an optimization differentiates the same structure at
/// many parameter values: only the chosen parameters change, and they are variables).
std::shared_ptr<const Tapes> tapes_for(const Problem& problem, const Texts& texts, const std::vector<std::string>& pvars);

/// Evaluates the tapes at one point and solves the KKT system along directions.
class Evaluator {
 public:
  /// law, law_var: the time law and the positions of its local form's symbols among the tapes'
  /// variables (kTimeLawSymbols; −1: not used), bound at each evaluation to t and s, ṡ, s̈ at t.
  Evaluator(const Tapes& T, const Eigen::VectorXd& pvals, const TimeLaw* law = nullptr,
            std::array<int, 4> law_var = {-1, -1, -1, -1})
      : T_(T), pvals_(pvals), x_(T.nv), law_(law), law_var_(law_var) {
    GR_.resize(T.n + T.m, T.nv);
    GZ_.resize(T.nz, T.nv);
    g_.resize(T.nv);
  }

  /// At (t, x) with the solved q̈, λ: the gradients of R and ż (and of τ, Φ, Φ̇ when `outputs`).
  void at(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& qdd, const Eigen::VectorXd& lam, bool outputs) {
    const int n = T_.n, m = T_.m, nz = T_.nz;
    x_[0] = t;
    x_.segment(T_.o_q, n) = x.head(n);
    x_.segment(T_.o_qd, n) = x.segment(n, n);
    if (nz) x_.segment(T_.o_z, nz) = x.segment(2 * n, nz);
    x_.segment(T_.o_qdd, n) = qdd;
    if (m) x_.segment(T_.o_lam, m) = lam;
    if (pvals_.size() > 0) x_.tail(pvals_.size()) = pvals_;
    if (law_) {
      const TimeLawValue v = law_->eval(t);
      const double local[4] = {t, v.s, v.ds, v.dds};
      for (int k = 0; k < 4; ++k)
        if (law_var_[k] >= 0) x_[law_var_[k]] = local[k];
    }
    residual_max_ = 0;
    for (int i = 0; i < n + m; ++i) {
      grad(T_.R[i], GR_, i, value_);
      residual_max_ = std::max(residual_max_, std::abs(value_));
    }
    for (int k = 0; k < nz; ++k) grad(T_.Zd[k], GZ_, k, value_);
    M_ = GR_.block(0, T_.o_qdd, n, n);
    A_ = GR_.block(n, T_.o_qdd, m, n);
    llt_.compute(M_);
    if (llt_.info() != Eigen::Success)
      throw NumericalFailure(t, "sensitivities: at t = " + fmt(t) + " s the mass matrix is not positive definite");
    if (m) {
      MinvAt_ = llt_.solve(A_.transpose());
      lu_.compute(A_ * MinvAt_);
    }
    if (outputs) {
      GT_.resize(n, T_.nv);
      GP_.resize(m, T_.nv);
      GPd_.resize(m, T_.nv);
      for (int i = 0; i < n; ++i) grad(T_.T[i], GT_, i, value_);
      for (int r = 0; r < m; ++r) grad(T_.Phi[r], GP_, r, value_);
      for (int r = 0; r < m; ++r) grad(T_.Phid[r], GPd_, r, value_);
    }
  }

  /// The largest |R| at the last point and the size of its terms: R vanishes at the solved q̈, λ
  /// when the symbolic and the numeric equations agree.
  double residual() const { return residual_max_; }
  double scale(const Eigen::VectorXd& qdd, const Eigen::VectorXd& lam) const {
    double s = 1.0 + M_.cwiseAbs().rowwise().sum().maxCoeff() * qdd.cwiseAbs().maxCoeff();
    if (T_.m) s += A_.cwiseAbs().colwise().sum().maxCoeff() * lam.cwiseAbs().maxCoeff();
    return s;
  }

  /// Along directions V (nv × c): δq̈, δλ, δż.
  void along(const Eigen::MatrixXd& V, Eigen::MatrixXd& dqdd, Eigen::MatrixXd& dlam, Eigen::MatrixXd& dzdot) {
    const int n = T_.n, m = T_.m;
    dR_.noalias() = -(GR_ * V);  // −δR: the right-hand sides r₁, r₂
    if (m) {
      r1_ = llt_.solve(dR_.topRows(n));  // M⁻¹ r₁
      tmp_.noalias() = A_ * r1_;
      tmp_ -= dR_.bottomRows(m);
      dlam = lu_.solve(tmp_);
      dqdd = r1_;
      dqdd.noalias() -= MinvAt_ * dlam;
    } else {
      dlam.resize(0, V.cols());
      dqdd = llt_.solve(dR_.topRows(n));
    }
    dzdot.noalias() = GZ_ * V;
  }

  const Eigen::MatrixXd& effort_gradient() const { return GT_; }
  const Eigen::MatrixXd& phi_gradient() const { return GP_; }
  const Eigen::MatrixXd& phid_gradient() const { return GPd_; }

 private:
  void grad(const Expression& e, Eigen::MatrixXd& G, int row, double& value) {
    e.evaluate(x_.data(), value, g_.data(), nullptr, ws_);
    G.row(row) = g_.transpose();
  }
  const Tapes& T_;
  Eigen::VectorXd pvals_, x_, g_;
  Eigen::MatrixXd GR_, GZ_, GT_, GP_, GPd_, M_, A_, MinvAt_, dR_, r1_, tmp_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  ExpressionWorkspace ws_;
  double value_ = 0, residual_max_ = 0;
  const TimeLaw* law_;
  std::array<int, 4> law_var_;
};

/// The time law's numbers and knots differentiated in the chosen parameters, natively: θ (the
/// task duration and the law's values, TimeLaw::values) through their scenario texts, the knots
/// t_i by the sums of the parts' durations (TimeLaw::duration_jet), and s, ṡ, s̈ at a fixed t by
/// TimeLaw::jet. Cost O(K·np) once, then O(np) per evaluation, for any K.
class LawDerivatives {
 public:
  LawDerivatives(const Problem& problem, const std::map<std::string, Eigen::RowVectorXd>& D, int np)
      : law_(problem.time_law.get()) {
    if (!law_) return;
    const std::vector<Number>& values = law_->values();
    theta_.setZero(static_cast<Eigen::Index>(values.size()) + 1, np);
    theta_.row(0) = text_derivative(problem, law_->task_duration_number().text, D, np);
    for (size_t j = 0; j < values.size(); ++j)
      theta_.row(static_cast<Eigen::Index>(j) + 1) = text_derivative(problem, values[j].text, D, np);
    const int K = law_->segments();
    knots_.setZero(K + 1, np);
    for (int i = 1; i <= K; ++i) {
      knots_.row(i) = knots_.row(i - 1);
      const TimeLaw::DurationJet dj = law_->duration_jet(i);
      for (int l = 0; l < 3; ++l)
        if (dj.theta[l] >= 0) knots_.row(i) += dj.d[l] * theta_.row(dj.theta[l]);
    }
  }
  const TimeLaw* law() const { return law_; }
  /// ∂t_i/∂p of knot i (0 … K).
  Eigen::RowVectorXd knot(int i) const { return knots_.row(i); }
  /// The local form's symbols along a direction with ∂t/∂p = tdot at t: rows t_c, s, ṡ, s̈ of V
  /// (at positions `rows`, −1: unused): ∂σ/∂p at fixed t + σ̇ tdot (σ̇ of s̈ is s⃛).
  void directions(double t, const Eigen::RowVectorXd& tdot, const std::array<int, 4>& rows, Eigen::MatrixXd& V) const {
    const TimeLaw::Jet j = law_->jet(t);
    const double rate[3] = {j.value.ds, j.value.dds, j.value.ddds};
    if (rows[0] >= 0) V.row(rows[0]) = tdot;
    for (int k = 0; k < 3; ++k) {
      if (rows[k + 1] < 0) continue;
      auto r = V.row(rows[k + 1]);
      r = rate[k] * tdot;
      for (int l = 0; l < 4; ++l)
        if (j.theta[l] >= 0 && j.d[k][l] != 0) r += j.d[k][l] * theta_.row(j.theta[l]);
      if (j.knot >= 0 && j.dknot[k] != 0) r += j.dknot[k] * knots_.row(j.knot);
    }
  }

 private:
  const TimeLaw* law_;
  Eigen::MatrixXd theta_, knots_;  ///< ∂θ/∂p (1 + values × np), ∂t_i/∂p (K + 1 × np)
};

}  // namespace refdyn::sensitivity_detail
