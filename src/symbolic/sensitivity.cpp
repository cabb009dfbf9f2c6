// Forward sensitivities of a plan (symbolic/sensitivity.hpp).
//
// The reference dynamics of order ≤ 2 solves, at every (t, x), the KKT system
//     R₁ = M(q) q̈ + c + g − Q(t, q, q̇, z; p) + Aᵀ λ = 0                    (n rows)
//     R₂ = A q̈ − rhs(t, q, q̇; p)                 = 0                    (m rows; rhs: the stabilized
//                                                                          right-hand side, −γ − 2αΦ̇ − β²Φ, …)
// whatever route (projection or Lagrange) computes it. Along a direction V of the inputs
// (t, q, q̇, z, p) with q̈*, λ* held, δR = ∇R·V; then M δq̈ + Aᵀ δλ = −δR₁, A δq̈ = −δR₂ gives the
// change of q̈ and λ, and ż changes by ∇ż·V. R₁, R₂, ż, the actuator effort
// τ = M q̈ + c + g − Q_passive + Σ_material Aᵀλ and Φ, Φ̇ come from generate_symbolic with the
// parameters as symbols; they are compiled once, with their gradients, into expression tapes
// whose variables are t, q, q̇, z, q̈, λ and the parameters that depend on the chosen ones
// (∇R with respect to q̈ and λ is M and Aᵀ, so the KKT matrix comes with them).
//
// S = ∂x/∂p is propagated through the plan's own RK4 steps (the same stages, the derivative of
// the RK4 map): K_s = ∂f/∂x S_s + ∂f/∂p, S_s = S + c_s h K_{s−1}, S ← S + h/6 (K₁ + 2K₂ + 2K₃ + K₄).
// When t1 depends on p, every sample t_k = t0 + (t_k − t0)/(t1 − t0)·(t1 − t0) moves with it: the
// total derivative at a sample adds the rate along the motion (ẋ, and for q̈, τ, Φ their rates from
// the same KKT system along the time direction) times (t_k − t0)/(t1 − t0)·∂t1/∂p.
#include "internal.hpp"
#include "tape.hpp"

#include "../expression/internal.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/symbolic/sensitivity.hpp"
#include "refdyn/symbolic/symbolic.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/QR>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <list>
#include <mutex>
#include <numbers>

namespace refdyn {

namespace {

using symbolic_detail::ex;

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
                                                               const std::vector<std::string>& chosen) {
  const int np = static_cast<int>(chosen.size());
  std::map<std::string, Eigen::RowVectorXd> D;
  std::vector<std::string> before;
  const std::map<std::string, double> consts{{"deg", std::numbers::pi / 180.0}};
  for (const auto& [name, text] : problem.texts.parameters) {
    Eigen::RowVectorXd d = Eigen::RowVectorXd::Zero(np);
    const auto it = std::find(chosen.begin(), chosen.end(), name);
    if (it != chosen.end()) {
      d[it - chosen.begin()] = 1.0;
    } else if (!text.empty() && !before.empty()) {
      const Expression e(text, before, consts, 1);
      std::vector<double> x(before.size()), g(before.size());
      for (size_t i = 0; i < before.size(); ++i) x[i] = problem.parameters.at(before[i]);
      double v = 0;
      e.evaluate(x.data(), v, g.data(), nullptr);
      for (size_t i = 0; i < before.size(); ++i)
        if (g[i] != 0) d += g[i] * D.at(before[i]);
    }
    D[name] = d;
    before.push_back(name);
  }
  return D;
}

/// d(text)/dp for a number written in the scenario (initial values, t1): "" is a constant.
Eigen::RowVectorXd text_derivative(const Problem& problem, const std::string& text,
                                   const std::map<std::string, Eigen::RowVectorXd>& D, int np) {
  Eigen::RowVectorXd d = Eigen::RowVectorXd::Zero(np);
  if (text.empty() || problem.texts.parameters.empty()) return d;
  if (const auto it = D.find(text); it != D.end()) return it->second;  // a parameter's name
  std::vector<std::string> names;
  std::vector<double> x;
  for (const auto& [name, _] : problem.texts.parameters) {
    names.push_back(name);
    x.push_back(problem.parameters.at(name));
  }
  const Expression e(text, names, {{"deg", std::numbers::pi / 180.0}}, 1);
  std::vector<double> g(names.size());
  double v = 0;
  e.evaluate(x.data(), v, g.data(), nullptr);
  for (size_t i = 0; i < names.size(); ++i)
    if (g[i] != 0) d += g[i] * D.at(names[i]);
  return d;
}

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

Texts symbolic_texts(const Problem& problem) {
  const LocalTimeLawForm local;  // a time law as its local form in four symbols (LawDirections)
  const SymbolicReferenceDynamics sym = generate_symbolic(problem);
  const SymbolicReferenceDynamics::Impl& S = sym.impl();
  if (S.jerk)
    throw Error("sensitivities are computed for problems of order ≤ 2; this one has a jerk row (hint: "
                "differentiate a plan of its acceleration-level form)");
  const int n = S.n, m = S.m;
  Texts out;
  std::lock_guard<std::mutex> lock(expr_detail::ginac_mutex());
  std::vector<GiNaC::realsymbol> lam;
  for (int r = 0; r < m; ++r) lam.emplace_back("lam(" + std::to_string(r) + ")");
  symbolic_detail::Tape tape;
  symbolic_detail::TapeScope scope(tape);
  symbolic_detail::FromGinac conv(tape, [](const GiNaC::symbol& s) { return s.get_name(); }, true);
  auto text = [&](const ex& e) { return symbolic_detail::expression_text(tape, conv(e)); };
  for (int i = 0; i < n; ++i) {
    ex r1 = S.cg[i] - S.Q[i], tau = S.cg[i] - (S.Q[i] - S.Qact[i]);
    for (int j = 0; j < n; ++j) {
      r1 += S.M[i * n + j] * S.qdd[j];
      tau += S.M[i * n + j] * S.qdd[j];
    }
    for (int r = 0; r < m; ++r) {
      r1 += S.A[r * n + i] * lam[r];
      if (S.row_origin[r] == "material") tau += S.A[r * n + i] * lam[r];
    }
    out.R.push_back(text(r1));
    out.T.push_back(text(tau));
  }
  for (int r = 0; r < m; ++r) {
    ex r2 = -S.rhs[r];
    for (int j = 0; j < n; ++j) r2 += S.A[r * n + j] * S.qdd[j];
    out.R.push_back(text(r2));
    out.Phi.push_back(text(S.phi[r]));
    out.Phid.push_back(text(S.phid[r]));
  }
  for (int k = 0; k < S.nz; ++k) out.Zd.push_back(text(S.zdot[k]));
  for (size_t k = 0; k < S.param_names.size(); ++k) {
    out.symbols.push_back(S.param_names[k]);
    out.values[S.param_names[k]] = S.param_values[k];
  }
  out.values["rd_alpha"] = S.alpha;
  out.values["rd_beta"] = S.beta;
  out.values["rd_beta1"] = S.beta1;
  return out;
}

std::shared_ptr<const Tapes> compile(const Problem& problem, const Texts& texts, const std::vector<std::string>& pvars) {
  auto tp = std::make_shared<Tapes>();
  Tapes& T = *tp;
  const Model& model = problem.model;
  T.n = model.nq;
  T.m = problem.constraints.rows();
  T.nz = problem.forces.num_states();
  T.pvars = pvars;
  std::vector<std::string> vars{"t"};
  T.o_q = 1;
  for (const auto& j : model.joint_name) vars.push_back("q(" + j + ")");
  T.o_qd = static_cast<int>(vars.size());
  for (const auto& j : model.joint_name) vars.push_back("qd(" + j + ")");
  T.o_z = static_cast<int>(vars.size());
  for (int k = 0; k < T.nz; ++k) vars.push_back("state(" + std::to_string(k) + ")");
  T.o_qdd = static_cast<int>(vars.size());
  for (const auto& j : model.joint_name) vars.push_back("qdd(" + j + ")");
  T.o_lam = static_cast<int>(vars.size());
  for (int r = 0; r < T.m; ++r) vars.push_back("lam(" + std::to_string(r) + ")");
  T.o_p = static_cast<int>(vars.size());
  for (const auto& p : pvars) vars.push_back(p);
  T.nv = static_cast<int>(vars.size());
  std::map<std::string, double> constants;
  for (const auto& [name, value] : texts.values)
    if (std::find(pvars.begin(), pvars.end(), name) == pvars.end()) constants[name] = value;
  ExpressionOptions opt;
  opt.derivative_order = 1;
  opt.specialize = false;
  // Generated texts, not user input: a time law's piecewise s(t), differentiated twice inside γ,
  // writes the rows of a 16-part law in ~70 KB.
  opt.max_length = std::size_t{1} << 24;
  auto build = [&](const std::vector<std::string>& src, std::vector<Expression>& dst) {
    for (const auto& s : src) dst.emplace_back(s, vars, constants, opt);
  };
  build(texts.R, T.R);
  build(texts.Zd, T.Zd);
  build(texts.T, T.T);
  build(texts.Phi, T.Phi);
  build(texts.Phid, T.Phid);
  return tp;
}

/// Compiled tapes, cached by their texts (an optimization differentiates the same structure at
/// many parameter values: only the chosen parameters change, and they are variables).
std::shared_ptr<const Tapes> tapes_for(const Problem& problem, const Texts& texts, const std::vector<std::string>& pvars) {
  std::string key = texts.key() + "|";
  for (const auto& p : pvars) key += p + ",";
  static std::mutex mutex;
  static std::list<std::pair<std::string, std::shared_ptr<const Tapes>>> cache;  // most recent first
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (auto it = cache.begin(); it != cache.end(); ++it)
      if (it->first == key) {
        cache.splice(cache.begin(), cache, it);
        return cache.front().second;
      }
  }
  auto tp = compile(problem, texts, pvars);
  std::lock_guard<std::mutex> lock(mutex);
  cache.emplace_front(key, tp);
  if (cache.size() > 8) cache.pop_back();
  return tp;
}

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

}  // namespace

namespace {
/// The checks of check_sensitivity_request before the symbolic forms.
void check_scope(const Problem& problem, const SensitivityOptions& options) {
  if (options.parameters.empty()) throw Error("sensitivities: name at least one parameter");
  std::vector<std::string> names;
  for (const auto& [name, _] : problem.texts.parameters) names.push_back(name);
  for (const auto& p : options.parameters) {
    if (std::find(names.begin(), names.end(), p) == names.end())
      throw Error("sensitivities: '" + p + "' is not a parameter of the scenario" + did_you_mean(p, names) +
                  (names.empty() ? " (it has no parameters: add a `parameters:` section)" : ""));
    if (std::count(options.parameters.begin(), options.parameters.end(), p) > 1)
      throw Error("sensitivities: parameter '" + p + "' is named twice");
  }
  if (problem.is_jerk_problem())
    throw Error("sensitivities are computed for problems of order ≤ 2; this one has a jerk row");
  if (!replays_stages(problem.integrator.method))
    throw Error(std::string("sensitivities are computed through the RK4 integrator; this plan uses method: ") +
                to_string(problem.integrator.method) + " (hint: integrator.method: rk4)");
  if (problem.options.stabilization != Stabilization::Baumgarte)
    throw Error("sensitivities are computed for Baumgarte stabilization; this problem uses stabilization: " +
                std::string(to_string(problem.options.stabilization)) + " (hint: stabilization: baumgarte)");
  if (problem.options.paper_literal_forces)
    throw Error("sensitivities are not available with the paper-literal force option (forces: paper_literal)");
}

/// The tapes' parameter variables: the parameters the texts name that depend on the chosen ones,
/// then the symbols of the time law's local form (LocalTimeLawForm) the texts name: variables,
/// bound at each evaluation, their directions from LawDerivatives (law_pos: their positions).
std::vector<std::string> parameter_variables(const Texts& texts, const std::map<std::string, Eigen::RowVectorXd>& D,
                                             const LawDerivatives& law, std::array<int, 4>& law_pos) {
  std::vector<std::string> pvars;
  for (const auto& s : texts.symbols)
    if (D.count(s) && !D.at(s).isZero(0)) pvars.push_back(s);
  law_pos = {-1, -1, -1, -1};  // among pvars
  for (int k = 0; k < 4; ++k)
    if (law.law() && std::find(texts.symbols.begin(), texts.symbols.end(), kTimeLawSymbols[k]) != texts.symbols.end()) {
      law_pos[k] = static_cast<int>(pvars.size());
      pvars.push_back(kTimeLawSymbols[k]);
    }
  return pvars;
}

/// The parameter variables' values and derivatives, and where the time law's symbols are.
struct ParameterValues {
  Eigen::VectorXd pvals;
  Eigen::MatrixXd Dp;
  std::array<int, 4> law_var{-1, -1, -1, -1}, law_row{-1, -1, -1, -1};  // in x (Evaluator), rows of V
  bool law_local = false;
};

/// Values and ∂/∂p of the parameter variables; the time law's symbols get their positions instead.
ParameterValues parameter_values(const Problem& problem, const Tapes& T, const std::vector<std::string>& pvars,
                                 const std::array<int, 4>& law_pos, const std::map<std::string, Eigen::RowVectorXd>& D,
                                 int np) {
  const int npv = static_cast<int>(pvars.size());
  ParameterValues pv;
  pv.pvals = Eigen::VectorXd::Zero(npv);
  pv.Dp = Eigen::MatrixXd::Zero(npv, np);
  for (int k = 0; k < npv; ++k) {
    const auto at = std::find(law_pos.begin(), law_pos.end(), k);
    if (at != law_pos.end()) {
      pv.law_var[at - law_pos.begin()] = T.o_p + k;
      pv.law_row[at - law_pos.begin()] = T.o_p + k;
      continue;
    }
    pv.pvals[k] = problem.parameters.at(pvars[k]);
    pv.Dp.row(k) = D.at(pvars[k]);
  }
  const auto& r = pv.law_row;
  pv.law_local = r[0] >= 0 || r[1] >= 0 || r[2] >= 0 || r[3] >= 0;
  return pv;
}

/// K = ∂f/∂x S + ∂f/∂t ∂t/∂p + ∂f/∂p at (t, x), with ẋ, q̈ and λ from the plan's own stages
/// (plan.stages: q̈, ż and λ of every RK4 stage), when it kept them for this problem: then the
/// reference dynamics are not evaluated again (measured on the paper's plan: this was a third of
/// the cost with one parameter); else from the reference dynamics.
class StageRates {
 public:
  StageRates(const Problem& problem, const Plan& plan, const Tapes& T, const ParameterValues& pv,
             const LawDerivatives& law, int np)
      : rd(problem.make_reference_dynamics()),
        ev(T, pv.pvals, pv.law_local ? law.law() : nullptr, pv.law_var),
        xdot(2 * T.n + T.nz),
        problem_(problem),
        T_(T),
        pv_(pv),
        law_(law),
        np_(np),
        V_buffer_(T.nv, np),
        ps_(plan.stages),
        stage_qdd_(T.n),
        stage_lam_(T.m) {
    const int n = T.n;
    stored_ = ps_.n == n && ps_.extra_size == T.nz + T.m && ps_.extra_size > 0 &&
              ps_.extra.size() == static_cast<size_t>(ps_.steps) * 4 * static_cast<size_t>(ps_.extra_size) &&
              ps_.data.size() == static_cast<size_t>(ps_.steps) * 4 * 3 * static_cast<size_t>(n);
  }

  /// Directions: rows t | q | q̇ | z | q̈ | λ | p (the last only for parameter columns).
  /// `tdot`: ∂t/∂p of the evaluation time t (a time on the plan's grid moves when t1 does).
  /// One buffer for every stage (the rows of q̈ and λ stay zero unless a caller fills them).
  Eigen::MatrixXd& directions(const Eigen::MatrixXd& S, double t, const Eigen::RowVectorXd& tdot) {
    const int n = T_.n, nz = T_.nz, npv = static_cast<int>(pv_.pvals.size());
    Eigen::MatrixXd& V = V_buffer_;
    V.setZero();
    V.row(0) = tdot;
    V.middleRows(T_.o_q, n) = S.topRows(n);
    V.middleRows(T_.o_qd, n) = S.middleRows(n, n);
    if (nz) V.middleRows(T_.o_z, nz) = S.bottomRows(nz);
    if (npv) V.bottomRows(npv) = pv_.Dp;
    if (pv_.law_local) law_.directions(t, tdot, pv_.law_row, V);
    return V;
  }

  /// ẋ into `xdot` and K into `K`; (step, stage) of the plan to take q̈, ż, λ from; step < 0:
  /// evaluate the reference dynamics.
  void rate(double t, const Eigen::VectorXd& x, const Eigen::MatrixXd& S, const Eigen::RowVectorXd& tdot,
            Eigen::MatrixXd& K, bool outputs, long step = -1, int stage = 0) {
    const int n = T_.n, m = T_.m, nz = T_.nz;
    if (stored_ && step >= 0 && step < ps_.steps) {
      const double* a = ps_.stage(step, stage) + 2 * n;
      const double* e = ps_.stage_extra(step, stage);
      xdot.head(n) = x.segment(n, n);
      for (int i = 0; i < n; ++i) stage_qdd_[i] = xdot[n + i] = a[i];
      for (int i = 0; i < nz; ++i) xdot[2 * n + i] = e[i];
      for (int r = 0; r < m; ++r) stage_lam_[r] = e[nz + r];
      ev.at(t, x, stage_qdd_, stage_lam_, outputs);
    } else {
      rd->derivative(t, x, xdot);
      ev.at(t, x, rd->qdd(), rd->lambda(), outputs);
    }
    ev.along(directions(S, t, tdot), dqdd, dlam, dzdot);
    K.resize(2 * n + nz, np_);
    K.topRows(n) = S.middleRows(n, n);
    K.middleRows(n, n) = dqdd;
    if (nz) K.bottomRows(nz) = dzdot;
  }

  /// The rates at a sample (into K and xdot_out: also the first stage of the next step) and what
  /// it records: t, ∂t/∂p, S, δq̈, the changes of the effort and of the rows.
  void record(double t, const Eigen::RowVectorXd& tdot, const Eigen::VectorXd& xs, const Eigen::MatrixXd& Sx,
              long step, Eigen::MatrixXd& K, Eigen::VectorXd& xdot_out, PlanSensitivity& out) {
    const int n = T_.n, m = T_.m;
    rate(t, xs, Sx, tdot, K, true, step, 0);
    xdot_out = xdot;
    Eigen::MatrixXd& V = directions(Sx, t, tdot);  // the buffer, with the changes of q̈ and λ, which τ reads
    V.middleRows(T_.o_qdd, n) = dqdd;
    if (m) V.middleRows(T_.o_lam, m) = dlam;
    Eigen::MatrixXd dph(m, np_);
    for (int r = 0; r < m; ++r)
      dph.row(r) = (problem_.constraints.row_order(r) == 1 ? ev.phid_gradient() : ev.phi_gradient()).row(r) * V;
    out.t.push_back(t);
    out.dt.push_back(tdot);
    out.dx.push_back(Sx);
    out.dqdd.push_back(dqdd);
    out.deffort.push_back(ev.effort_gradient() * V);
    out.dphi.push_back(std::move(dph));
  }

  std::unique_ptr<ReferenceDynamics> rd;
  Evaluator ev;
  Eigen::VectorXd xdot;
  Eigen::MatrixXd dqdd, dlam, dzdot;

 private:
  const Problem& problem_;
  const Tapes& T_;
  const ParameterValues& pv_;
  const LawDerivatives& law_;
  int np_;
  Eigen::MatrixXd V_buffer_;
  const ReferenceStages& ps_;
  bool stored_ = false;
  Eigen::VectorXd stage_qdd_, stage_lam_;
};

/// ∂x(t0)/∂p of the initial values as the scenario writes them.
Eigen::MatrixXd initial_sensitivity(const Problem& problem, const std::map<std::string, Eigen::RowVectorXd>& D,
                                    int n, int nx, int np) {
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(nx, np);
  for (int i = 0; i < n; ++i) {
    S.row(i) = text_derivative(problem, problem.texts.q0[static_cast<size_t>(i)], D, np);
    if (static_cast<size_t>(i) < problem.texts.qd0.size())
      S.row(n + i) = text_derivative(problem, problem.texts.qd0[static_cast<size_t>(i)], D, np);
  }
  return S;
}

/// make_consistent moved q0, then q̇0, onto the rows by minimum-norm Newton steps on the
/// dependent coordinates: x* = x_raw − K⁺ r (K: the rows' columns of the dependent
/// coordinates). Its derivative is dx*_dep = dx_raw_dep − K⁺ (∇r · V), exact when K has full
/// column rank (then K⁺K = I: the implicit-function rule) or when x_raw already met the rows
/// (r = 0, so the change of K⁺ does not count); otherwise refused.
void project_initial_sensitivity(const Problem& problem, const Tapes& T, StageRates& rates, double t0,
                                 const Eigen::VectorXd& x, Eigen::MatrixXd& S, int np) {
  const int n = T.n, m = T.m;
  const Eigen::RowVectorXd no_time = Eigen::RowVectorXd::Zero(np);
  rates.rd->derivative(t0, x, rates.xdot);
  rates.ev.at(t0, x, rates.rd->qdd(), rates.rd->lambda(), true);
  const std::vector<int>& dep = rates.rd->dependent();
  std::vector<int> pos, vel;
  for (int r = 0; r < m; ++r) {
    const int o = problem.constraints.row_order(r);
    if (o == 0) pos.push_back(r);
    if (o <= 1) vel.push_back(r);
  }
  auto solve_dependent = [&](const Eigen::MatrixXd& G, int offset, const std::vector<int>& rows, int block,
                             const Eigen::VectorXd& moved, const char* what) {
    if (rows.empty() || dep.empty()) return;
    const Eigen::MatrixXd V = rates.directions(S, t0, no_time);
    Eigen::MatrixXd r(rows.size(), np), K(rows.size(), dep.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      r.row(i) = G.row(rows[i]) * V;
      for (size_t a = 0; a < dep.size(); ++a) K(i, a) = G(rows[i], offset + dep[a]);
    }
    const auto cod = K.completeOrthogonalDecomposition();
    if (cod.rank() < static_cast<Eigen::Index>(dep.size()) && moved.size() && moved.cwiseAbs().maxCoeff() > 0)
      throw Error(std::string("sensitivities: the initial ") + what +
                  " was projected onto rows that leave some dependent coordinates free; its derivative depends "
                  "on how the projection moved it (hint: write initial values that meet the constraints, "
                  "e.g. from closed-form inverse kinematics with the parameters)");
    const Eigen::MatrixXd step = cod.solve(r);
    for (size_t a = 0; a < dep.size(); ++a) S.row(block * n + dep[a]) -= step.row(a);
  };
  solve_dependent(rates.ev.phi_gradient(), T.o_q, pos, 0, problem.initial_dq, "position");
  solve_dependent(rates.ev.phid_gradient(), T.o_qd, vel, 1, problem.initial_dqd, "velocity");
}

/// ∂t/∂p of the grid's times. Uniform grid: t0 + (k + c)·h with h = (t1 − t0)/nsteps, so a time
/// moves by (t − t0)/(t1 − t0)·∂t1/∂p. With breakpoints (a time law's knots, IntegratorOptions::
/// breakpoints) each part [b_j, b_{j+1}] has its own n_j equal steps, and its grid moves with its
/// ends: b_j + (k + c)/n_j·(b_{j+1} − b_j). The knots, where s̈ jumps, stay on the grid as they
/// move, so the RK4 map differentiated as it is follows them: no jump condition is needed.
class GridRates {
 public:
  GridRates(const Problem& problem, const Rk4Grid& grid, const LawDerivatives& law, const Eigen::RowVectorXd& dt_end,
            int np)
      : dstart(np), dh(np), grid_(grid), t0_(problem.integrator.t0), t1_(problem.integrator.t1), dt_end_(dt_end),
        nsteps_(grid.steps()) {
    if (grid.uniform()) return;
    part_end_.push_back(Eigen::RowVectorXd::Zero(np));
    for (long k = 0; k < nsteps_; ++k)
      if (k == 0 || grid.part(k) != grid.part(k - 1)) part_first_.push_back(k);
    part_first_.push_back(nsteps_);
    const std::vector<double>& knots = problem.time_law_knots;
    for (size_t j = 1; j + 1 < part_first_.size(); ++j) {
      const double b = grid.start(part_first_[j]);
      const auto it = std::find(knots.begin(), knots.end(), b);
      if (!law.law() || it == knots.end())
        throw Error("sensitivities: the integrator's breakpoint t = " + fmt(b) + " s is not a knot of the time law");
      part_end_.push_back(law.knot(static_cast<int>(it - knots.begin())));
    }
    part_end_.push_back(dt_end);
  }

  /// ∂t/∂p of a time t on the uniform grid.
  Eigen::RowVectorXd time_rate(double t) const { return (t - t0_) / (t1_ - t0_) * dt_end_; }

  /// ∂/∂p of the start of step k and of its size, into dstart and dh.
  void step_rates(long k) {
    if (grid_.uniform()) {
      dstart = time_rate(grid_.start(k));
      dh = dt_end_ / static_cast<double>(nsteps_);
      return;
    }
    const size_t j = static_cast<size_t>(grid_.part(k));
    const double nj = static_cast<double>(part_first_[j + 1] - part_first_[j]);
    dh = (part_end_[j + 1] - part_end_[j]) / nj;
    dstart = part_end_[j] + static_cast<double>(k - part_first_[j]) * dh;
  }

  /// ∂t/∂p of stage time t = start + c h of step k (after step_rates(k)).
  Eigen::RowVectorXd stage_rate(double t, double c) const {
    return grid_.uniform() ? time_rate(t) : Eigen::RowVectorXd(dstart + c * dh);
  }

  Eigen::RowVectorXd dstart, dh;

 private:
  const Rk4Grid& grid_;
  double t0_, t1_;
  Eigen::RowVectorXd dt_end_;
  long nsteps_;
  std::vector<Eigen::RowVectorXd> part_end_;  // ∂b_j/∂p, j = 0 … B + 1
  std::vector<long> part_first_;              // the first step of each part
};

/// S through the plan's RK4 steps, recording every sample from t0 on: the RK4 map
/// x⁺ = x + h/6 (k₁ + 2k₂ + 2k₃ + k₄), stages at t + c h, differentiated as it is, with h and the
/// stage times moving with the grid.
void propagate(const Problem& problem, size_t samples, const Rk4Grid& grid, GridRates& gr, StageRates& rates,
               Eigen::VectorXd& x, Eigen::MatrixXd& S, PlanSensitivity& out) {
  const double t0 = problem.integrator.t0;
  const long nsteps = grid.steps();
  const Eigen::Index nx = S.rows(), np = S.cols();
  // A sample's evaluation is also the first stage of the next step (same t, x, S): kept.
  Eigen::MatrixXd K_sample;
  Eigen::VectorXd xdot_sample;
  // Evaluated (not the stored stage): the check below compares the two routes.
  rates.record(t0, gr.time_rate(t0), x, S, -1, K_sample, xdot_sample, out);
  if (!(rates.ev.residual() <= 1e-7 * rates.ev.scale(rates.rd->qdd(), rates.rd->lambda())))
    throw Error("sensitivities: the generated equations do not match the reference dynamics at t0 (KKT residual " +
                fmt(rates.ev.residual()) + "); please report this scenario");
  static constexpr double c[4] = {0.0, 0.5, 0.5, 1.0}, w[4] = {1.0, 2.0, 2.0, 1.0};
  Eigen::MatrixXd Ss, Kst[4], Sacc(nx, np);
  Eigen::VectorXd kst[4], xs(nx), xacc(nx);
  bool sampled = true;  // the step starts on a sample (recorded, its evaluation kept)
  for (long k = 0; k < nsteps && out.t.size() < samples; ++k) {
    const double t = grid.start(k), h = grid.size(k);
    gr.step_rates(k);
    const Eigen::RowVectorXd& dh = gr.dh;
    xacc.setZero();
    Sacc.setZero();
    for (int st = 0; st < 4; ++st) {
      Ss = S;
      xs = x;
      if (st > 0) {
        xs += (c[st] * h) * kst[st - 1];
        Ss += (c[st] * h) * Kst[st - 1] + c[st] * kst[st - 1] * dh;
      }
      const double ts = st == 3 ? grid.stage_time(k, 1.0) : t + c[st] * h;  // as integrate_rk4
      if (st == 0 && sampled) {
        Kst[0].swap(K_sample);
        kst[0].swap(xdot_sample);
      } else {
        rates.rate(ts, xs, Ss, gr.stage_rate(ts, c[st]), Kst[st], false, k, st);
        kst[st] = rates.xdot;
      }
      xacc += w[st] * kst[st];
      Sacc += w[st] * Kst[st];
    }
    x += (h / 6.0) * xacc;
    S += (h / 6.0) * Sacc + (1.0 / 6.0) * xacc * dh;
    sampled = grid.sample(k);
    if (sampled)
      rates.record(grid.end(k), grid.uniform() ? gr.time_rate(grid.end(k)) : Eigen::RowVectorXd(gr.dstart + dh * 1.0),
                   x, S, k + 1, K_sample, xdot_sample, out);
  }
}
}  // namespace

void check_sensitivity_request(const Problem& problem, const SensitivityOptions& options) {
  check_scope(problem, options);
  const LocalTimeLawForm local;      // as plan_sensitivity generates them (symbolic_texts)
  (void)generate_symbolic(problem);  // every kind has a symbolic form
}

PlanSensitivity plan_sensitivity(const Problem& problem, const Plan& plan, const SensitivityOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  check_scope(problem, options);  // the symbolic forms are checked by symbolic_texts below
  if (plan.t.empty()) throw Error("sensitivities: the plan has no samples");

  const int np = static_cast<int>(options.parameters.size());
  const auto D = parameter_derivatives(problem, options.parameters);
  const Texts texts = symbolic_texts(problem);
  const LawDerivatives law(problem, D, np);
  std::array<int, 4> law_pos;
  const std::vector<std::string> pvars = parameter_variables(texts, D, law, law_pos);
  const std::shared_ptr<const Tapes> tp = tapes_for(problem, texts, pvars);
  const Tapes& T = *tp;
  const ParameterValues pv = parameter_values(problem, T, pvars, law_pos, D, np);
  if (!text_derivative(problem, problem.texts.t0, D, np).isZero(0))
    throw Error("sensitivities: integrator.t0 depends on a chosen parameter (not supported: write t0 as a number)");
  PlanSensitivity out;
  out.parameters = options.parameters;
  out.dt_end = problem.t1_is_law_end && law.law() ? law.knot(law.law()->segments())
                                                  : text_derivative(problem, problem.texts.t1, D, np);

  StageRates rates(problem, plan, T, pv, law, np);
  Eigen::VectorXd x = rates.rd->make_state(problem.q0, problem.qd0);
  Eigen::MatrixXd S = initial_sensitivity(problem, D, T.n, 2 * T.n + T.nz, np);
  if (problem.project_initial && T.m > 0)
    project_initial_sensitivity(problem, T, rates, problem.integrator.t0, x, S, np);
  const Rk4Grid grid(problem.integrator);  // the plan's grid (as integrate_rk4 steps it)
  GridRates grid_rates(problem, grid, law, out.dt_end, np);
  propagate(problem, plan.t.size(), grid, grid_rates, rates, x, S, out);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace refdyn
