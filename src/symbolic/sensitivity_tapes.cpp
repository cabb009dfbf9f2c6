// The symbolic forms of a plan's equations (R₁, R₂, ż, τ, Φ, Φ̇ from generate_symbolic, the
// parameters as symbols) compiled into expression tapes with their gradients, and the parameters'
// total derivatives: the inputs of the forward sensitivities (sensitivity.cpp).
#include "sensitivity_internal.hpp"

#include "internal.hpp"
#include "tape.hpp"

#include "../expression/internal.hpp"

#include "refdyn/symbolic/symbolic.hpp"

#include <algorithm>
#include <list>
#include <mutex>
#include <numbers>

namespace refdyn::sensitivity_detail {

using symbolic_detail::ex;

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

namespace {
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

}  // namespace

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

}  // namespace refdyn::sensitivity_detail
