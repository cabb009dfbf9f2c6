// generate_symbolic: a Problem's reference dynamics as GiNaC expressions (see symbolic.hpp).
#include "internal.hpp"

#include "../expression/internal.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/symbolic_form.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/reference/jerk.hpp"

#include <algorithm>
#include <chrono>
#include <cctype>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>

namespace refdyn {

using symbolic_detail::ex;
using symbolic_detail::Vec3s;

namespace {

std::string latex_name(const std::string& name) {
  // a_1b → a_{1b}; other underscores escaped
  std::string out;
  const auto us = name.find('_');
  std::string base = us == std::string::npos ? name : name.substr(0, us);
  std::string sub = us == std::string::npos ? "" : name.substr(us + 1);
  if (us == std::string::npos) {
    // trailing digits become a subscript: z0 → z_{0}
    size_t k = base.size();
    while (k > 1 && std::isdigit(static_cast<unsigned char>(base[k - 1]))) --k;
    if (k < base.size()) {
      sub = base.substr(k);
      base = base.substr(0, k);
    }
  }
  auto esc = [](const std::string& s) {
    std::string r;
    for (char ch : s) {
      if (ch == '_') r += "\\_";
      else r += ch;
    }
    return r;
  };
  static const char* greek[] = {"alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "kappa",
                                "lambda", "mu", "nu", "xi", "rho", "sigma", "tau", "phi", "chi", "psi", "omega",
                                "Gamma", "Delta", "Theta", "Lambda", "Phi", "Psi", "Omega"};
  std::string b = base.size() > 1 ? "\\mathit{" + esc(base) + "}" : esc(base);
  for (const char* g : greek)
    if (base == g) b = std::string("\\") + g;
  return sub.empty() ? b : b + "_{" + esc(sub) + "}";
}

/// Binds the variables of the expression language (symbolic_form.hpp) to expressions.
class Binder {
 public:
  explicit Binder(SymbolicReferenceDynamics::Impl& impl) : impl_(impl) {}
  void bind(const std::string& name, const ex& value) {
    names_.push_back(name);
    values_.push_back(value);
  }
  void pop(std::size_t n) {
    names_.resize(names_.size() - n);
    values_.resize(values_.size() - n);
  }
  /// Parses text with the bound variables and the form's parameters (kept symbolic).
  ex parse(const std::string& text, const std::map<std::string, double>& parameters, const std::string& where) {
    std::vector<std::string> vars = names_;
    std::vector<ex> vals = values_;
    std::vector<const std::pair<const std::string, double>*> params;  // for vars[names_.size() + k]
    for (const auto& entry : parameters) {
      if (std::find(vars.begin(), vars.end(), entry.first) != vars.end()) continue;  // a variable wins
      vars.push_back(entry.first);
      params.push_back(&entry);
    }
    std::vector<GiNaC::realsymbol> syms;
    syms.reserve(vars.size());
    for (const auto& v : vars) syms.emplace_back(v);
    ex e;
    try {
      e = expr_detail::symbolic_value(text, vars, syms);
    } catch (const Error& err) {
      throw Error(where + ": " + err.what());
    }
    GiNaC::exmap sub;
    for (size_t i = 0; i < syms.size(); ++i) {
      if (!e.has(syms[i])) continue;
      // a parameter becomes a symbol of the generated code only when a formula uses it
      sub[syms[i]] = i < vals.size() ? vals[i]
                                     : parameter(params[i - vals.size()]->first, params[i - vals.size()]->second, where);
    }
    e = symbolic_detail::exact(e);  // exact numbers: results independent of GiNaC's order
    return sub.empty() ? e : e.subs(sub, GiNaC::subs_options::no_pattern);
  }

 private:
  ex parameter(const std::string& name, double value, const std::string& where) {
    auto& names = impl_.param_names;
    const auto it = std::find(names.begin(), names.end(), name);
    if (it != names.end()) {
      const size_t k = static_cast<size_t>(it - names.begin());
      if (!(impl_.param_values[k] == value))
        throw Error(where + ": parameter '" + name + "' = " + fmt(value) + " differs from the value " +
                    fmt(impl_.param_values[k]) + " used elsewhere (hint: one name, one value)");
      return impl_.params[k];
    }
    names.push_back(name);
    impl_.param_values.push_back(value);
    impl_.params.emplace_back(name, latex_name(name));
    return impl_.params.back();
  }

  SymbolicReferenceDynamics::Impl& impl_;
  std::vector<std::string> names_;
  std::vector<ex> values_;
};

/// A form's parameters with the scenario's added (the form's own win) when its texts contain
/// scenario texts of numbers (Number, from the reader's Quantity), which name them.
std::optional<SymbolicForm> with_scenario_parameters(std::optional<SymbolicForm> form, const Problem& problem) {
  if (form && form->scenario_texts)
    for (const auto& [name, v] : problem.parameters) form->parameters.emplace(name, v);
  return form;
}

std::string identifier(const std::string& s) {
  std::string r;
  for (char ch : s) r += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  if (r.empty() || std::isdigit(static_cast<unsigned char>(r[0]))) r = "m" + r;
  return r;
}

/// The total time derivative along the motion, by the chain rule over the expression graph
/// (forward mode: each node's rate once, so shared sub-expressions stay shared; GiNaC's diff
/// would unfold the graph into a tree). `leaf` gives the rate of each symbol (absent: 0).
class TotalRate {
 public:
  explicit TotalRate(GiNaC::exmap leaf) : leaf_(std::move(leaf)) {}
  ex operator()(const ex& e) {
    if (GiNaC::is_a<GiNaC::numeric>(e) || GiNaC::is_a<GiNaC::constant>(e)) return 0;
    if (GiNaC::is_a<GiNaC::symbol>(e)) {
      const auto it = leaf_.find(e);
      return it == leaf_.end() ? ex(0) : it->second;
    }
    const auto hit = memo_.find(e);
    if (hit != memo_.end()) return hit->second;
    ex r = 0;
    if (GiNaC::is_a<GiNaC::add>(e)) {
      GiNaC::exvector terms;
      for (size_t i = 0; i < e.nops(); ++i) terms.push_back((*this)(e.op(i)));
      r = GiNaC::add(terms);
    } else if (GiNaC::is_a<GiNaC::mul>(e)) {
      GiNaC::exvector terms;
      for (size_t i = 0; i < e.nops(); ++i) {
        const ex d = (*this)(e.op(i));
        if (d.is_zero()) continue;
        GiNaC::exvector f;
        for (size_t j = 0; j < e.nops(); ++j) f.push_back(j == i ? d : e.op(j));
        terms.push_back(GiNaC::mul(f));
      }
      r = GiNaC::add(terms);
    } else if (GiNaC::is_a<GiNaC::power>(e)) {
      const ex b = e.op(0), p = e.op(1);
      const ex db = (*this)(b), dp = (*this)(p);
      if (!db.is_zero()) r += p * GiNaC::pow(b, p - 1) * db;
      if (!dp.is_zero()) r += e * GiNaC::log(b) * dp;
    } else if (GiNaC::is_a<GiNaC::function>(e)) {
      const unsigned serial = GiNaC::ex_to<GiNaC::function>(e).get_serial();
      for (size_t k = 0; k < e.nops(); ++k) {
        const ex d = (*this)(e.op(k));
        if (d.is_zero()) continue;
        // ∂f/∂(argument k) at the arguments: f with a fresh symbol in place k, differentiated
        const GiNaC::realsymbol u("rd_u");
        GiNaC::exvector args;
        for (size_t j = 0; j < e.nops(); ++j) args.push_back(j == k ? ex(u) : e.op(j));
        const ex partial = GiNaC::function(serial, args).diff(u);
        r += partial.subs(GiNaC::exmap{{u, e.op(k)}}, GiNaC::subs_options::no_pattern) * d;
      }
    } else {
      throw Error("generate: cannot differentiate the expression " + expr_detail::to_text(e) + " with respect to time");
    }
    memo_.emplace(e, r);
    return r;
  }

 private:
  GiNaC::exmap leaf_;
  std::map<ex, ex, GiNaC::ex_is_less> memo_;
};

/// The constraints: Φ (or c), Φ̇, A, γ by differentiation of each constraint's symbolic form.
void generate_constraints(const Problem& problem, SymbolicReferenceDynamics::Impl& S, Binder& B) {
  const Model& model = problem.model;
  const int n = model.nq;
  const ConstraintSet& cs = problem.constraints;
  // Derivatives by the chain rule over the graph (TotalRate: each node once, so shared
  // sub-expressions stay shared; GiNaC's diff would unfold the graph into a tree): along the
  // motion with q̇ (Φ̇, γ: t → 1, q → q̇, q̇ held), and the partials by q_i, q̇_i, q̈_i (A).
  GiNaC::exmap motion{{S.t, 1}};
  for (int i = 0; i < n; ++i) motion[S.q[i]] = S.qd[i];
  TotalRate along(motion);
  std::vector<std::unique_ptr<TotalRate>> by_q(n), by_qd(n), by_qdd(n);  // made when needed
  auto partial = [](std::vector<std::unique_ptr<TotalRate>>& by, const GiNaC::realsymbol& s, int i, const ex& f) {
    if (!by[i]) by[i] = std::make_unique<TotalRate>(GiNaC::exmap{{s, 1}});
    return (*by[i])(f);
  };
  S.phi.assign(S.m, 0);
  S.phid.assign(S.m, 0);
  S.gamma.assign(S.m, 0);
  S.A.assign(static_cast<size_t>(S.m) * n, 0);
  for (int k = 0; k < cs.size(); ++k) {
    const Constraint& c = *cs.constraints()[k];
    const std::string where = "generate: constraint '" + c.name + "'";
    std::optional<SymbolicForm> form = with_scenario_parameters(c.symbolic(problem.model), problem);
    if (!form && c.order() == 3)
      if (const JerkConstraintPtr j = jerk_constraint_of(c)) {
        form = SymbolicForm{};
        form->rows = {j->text()};
        form->parameters = problem.parameters;
      }
    if (!form)
      throw Error(where + " (" + c.describe() + ") has no symbolic form (hint: write it as an `expression` constraint)");
    if (static_cast<int>(form->rows.size()) != c.rows())
      throw Error(where + ": its symbolic form has " + std::to_string(form->rows.size()) + " rows, expected " +
                  std::to_string(c.rows()));
    for (int r = 0; r < c.rows(); ++r) {
      const int row = cs.row_offset(k) + r;
      // The generator writes a time law into the rows as one expression of t: with many knots the
      // text passes the expression limit, and the engine's generic hint (split it) cannot be followed.
      const size_t limit = ExpressionOptions{}.max_length;
      if (problem.time_law && form->rows[r].size() > limit)
        throw Error(where + ": with the scenario's time law of " +
                    std::to_string(problem.time_law_knots.empty() ? 0 : problem.time_law_knots.size() - 1) +
                    " parts written into it as one expression of t, the row is " +
                    std::to_string(form->rows[r].size()) + " characters long, more than the generator's limit of " +
                    std::to_string(limit) +
                    " (hint: generate the scenario without its time_law: section, i.e. the equations in the task's "
                    "own time, which the law then maps to t; or use a law of fewer parts)");
      const ex f = B.parse(form->rows[r], form->parameters, where);
      S.row_names.push_back(cs.row_name(row));
      S.row_origin.push_back(to_string(c.origin));
      S.row_order.push_back(static_cast<char>(c.order()));
      S.phi[row] = f;
      for (int i = 0; i < n; ++i) {
        if (c.order() < 2 && f.has(S.qdd[i]))
          throw Error(where + ": a position or velocity constraint depends on the acceleration of " + model.joint_name[i]);
        if (c.order() < 3 && f.has(S.qddd[i]))
          throw Error(where + ": a constraint of order " + std::to_string(c.order()) + " depends on the jerk of " +
                      model.joint_name[i] + " (hint: order: jerk)");
      }
      if (c.order() == 3) {
        // B(t, q, q̇) q⃛ + s(t, q, q̇, q̈) = 0: B = ∂f/∂q⃛, s = f at q⃛ = 0; B must not depend on
        // q̈ or q⃛ (as JerkConstraint requires). Imposed exactly at jerk level: B q⃛ = −s.
        GiNaC::exmap zero;
        for (int i = 0; i < n; ++i) zero[S.qddd[i]] = 0;
        for (int i = 0; i < n; ++i) {
          const ex Bi = f.diff(S.qddd[i]);
          for (int l = 0; l < n; ++l)
            if (Bi.has(S.qdd[l]) || Bi.has(S.qddd[l]))
              throw Error(where + ": the coefficient of the jerk of " + model.joint_name[i] + " depends on the " +
                          (Bi.has(S.qdd[l]) ? "acceleration" : "jerk") + " of " + model.joint_name[l] +
                          " (a jerk row is B(t, q, qd) qddd + s = 0)");
          S.A[static_cast<size_t>(row) * n + i] = Bi;
        }
        S.gamma[row] = f.subs(zero, GiNaC::subs_options::no_pattern);
        S.phi[row] = 0;
        S.phid[row] = 0;
      } else if (c.order() == 2) {
        // B q̈ + s = 0, linear in q̈ (checked by the kind): A = B = ∂f/∂q̈, γ = s = f at q̈ = 0,
        // imposed exactly (A q̈ = −γ, no stabilisation); Φ and Φ̇ are reported as 0, as the engine does.
        GiNaC::exmap zero;
        for (int i = 0; i < n; ++i) zero[S.qdd[i]] = 0;
        for (int i = 0; i < n; ++i) S.A[static_cast<size_t>(row) * n + i] = partial(by_qdd, S.qdd[i], i, f);
        S.gamma[row] = f.subs(zero, GiNaC::subs_options::no_pattern);
        S.phi[row] = 0;
        S.phid[row] = 0;
      } else if (!c.first_order()) {
        for (int i = 0; i < n; ++i)
          if (f.has(S.qd[i]))
            throw Error(where + ": a position constraint depends on the velocity " + model.joint_name[i]);
        // Φ̇ = A q̇ + ∂Φ/∂t, γ = Σ ∂Φ̇/∂q_i q̇_i + ∂Φ̇/∂t
        for (int i = 0; i < n; ++i) S.A[static_cast<size_t>(row) * n + i] = partial(by_q, S.q[i], i, f);
        const ex fd = along(f);
        S.phid[row] = fd;
        S.gamma[row] = along(fd);
      } else {
        // A = ∂c/∂q̇, γ = Σ ∂c/∂q_i q̇_i + ∂c/∂t
        for (int i = 0; i < n; ++i) S.A[static_cast<size_t>(row) * n + i] = partial(by_qd, S.qd[i], i, f);
        S.phid[row] = f;
        S.gamma[row] = along(f);
      }
    }
  }
}

/// The force elements: Q and ż from each element's symbolic form.
void generate_forces(const Problem& problem, SymbolicReferenceDynamics::Impl& S, Binder& B) {
  const int n = problem.model.nq;
  S.Q.assign(n, 0);
  S.Qact.assign(n, 0);
  S.zdot.assign(S.nz, 0);
  for (size_t k = 0; k < problem.forces.elements().size(); ++k) {
    const ForceElement& e = *problem.forces.elements()[k];
    const std::string where = "generate: force element " + e.name();
    std::optional<SymbolicForm> form = with_scenario_parameters(e.symbolic(problem.model), problem);
    if (!form) throw Error(where + " has no symbolic form");
    const int off = problem.forces.state_offset(static_cast<int>(k));
    if (static_cast<int>(form->state_rates.size()) != e.num_states() || form->joints.size() != form->rows.size())
      throw Error(where + ": inconsistent symbolic form");
    std::size_t bound = 0;
    for (int s = 0; s < e.num_states(); ++s, ++bound) B.bind("z(" + std::to_string(s) + ")", S.z[off + s]);
    for (const auto& [fname, text] : form->functions) {
      const ex f = B.parse(text, form->parameters, where + ": function " + fname);
      B.bind(fname, f);
      B.bind("d_" + fname, f.diff(S.t));
      bound += 2;
    }
    std::vector<ex> rates;
    for (int s = 0; s < e.num_states(); ++s) rates.push_back(B.parse(form->state_rates[s], form->parameters, where));
    for (int s = 0; s < e.num_states(); ++s, ++bound) {
      S.zdot[off + s] = rates[s];
      B.bind("zdot(" + std::to_string(s) + ")", rates[s]);
    }
    for (size_t r = 0; r < form->rows.size(); ++r) {
      const int j = form->joints[r];
      if (j < 0 || j >= n) throw Error(where + ": joint index out of range");
      const ex Qr = B.parse(form->rows[r], form->parameters, where);
      S.Q[j] += Qr;
      if (e.actuator()) S.Qact[j] += Qr;
    }
    B.pop(bound);
  }
}

/// The jerk level (docs/generate.md, "Jerk problems"): R = M q̈ + c + g − Q and its rate Ṙ at
/// q⃛ = 0, G and Ġ, and per row ψ and b: every row of order ≤ 2 in its stabilized acceleration
/// form ψ (A q̈ + γ + 2αΦ̇ + β²Φ, A q̈ + γ + β₁c, or A q̈ + γ), imposed as ψ̇ + κψ = 0, i.e.
/// A q⃛ = −ψ̇|q⃛=0 − κψ; every jerk row as B q⃛ = −s. The rates are total time derivatives along the
/// motion (t, q → q̇, q̇ → q̈, q̈ → q⃛ = 0, z → ż), exact.
void generate_jerk_level(SymbolicReferenceDynamics::Impl& S, const symbolic_detail::SymbolicModel& sm) {
  const int n = S.n, m = S.m;
  GiNaC::exmap leaf;
  leaf[S.t] = 1;
  for (int i = 0; i < n; ++i) {
    leaf[S.q[i]] = S.qd[i];
    leaf[S.qd[i]] = S.qdd[i];
  }
  for (int k = 0; k < S.nz; ++k) leaf[S.z[k]] = S.zdot[k];
  TotalRate rate(leaf);
  const std::vector<ex> qd(S.qd.begin(), S.qd.end()), qdd(S.qdd.begin(), S.qdd.end());
  const std::vector<ex> tau = sm.inverse_dynamics(qd, qdd, true);  // M q̈ + c + g (Newton–Euler)
  S.R.resize(n);
  S.Rdot.resize(n);
  for (int i = 0; i < n; ++i) {
    S.R[i] = tau[i] - S.Q[i];
    S.Rdot[i] = rate(S.R[i]);
  }
  S.G.assign(static_cast<size_t>(m) * n, 0);
  S.Gdot.assign(static_cast<size_t>(m) * n, 0);
  S.psi.assign(m, 0);
  S.b.assign(m, 0);
  for (int r = 0; r < m; ++r) {
    for (int i = 0; i < n; ++i) {
      S.G[r * n + i] = S.A[r * n + i];
      S.Gdot[r * n + i] = rate(S.A[r * n + i]);
    }
    if (S.row_order[r] == 3) {
      S.b[r] = -S.gamma[r];
      continue;
    }
    ex psi = S.gamma[r];
    for (int i = 0; i < n; ++i) psi += S.A[r * n + i] * S.qdd[i];
    if (S.row_order[r] == 0) psi += 2 * S.alpha_s * S.phid[r] + S.beta_s * S.beta_s * S.phi[r];
    if (S.row_order[r] == 1) psi += S.beta1_s * S.phi[r];
    S.psi[r] = psi;
    S.b[r] = -rate(psi) - S.kappa_s * psi;
  }
}

/// The prefix of the generated C names: the option, else rd_<problem name>_; a C identifier.
std::string symbol_prefix(const Problem& problem, const SymbolicOptions& options) {
  const std::string prefix = options.prefix.empty() ? "rd_" + identifier(problem.name) + "_" : options.prefix;
  bool ok = !prefix.empty() && (std::isalpha(static_cast<unsigned char>(prefix[0])) || prefix[0] == '_');
  for (char ch : prefix) ok = ok && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_');
  if (!ok) throw Error("generate: prefix '" + options.prefix + "' is not a C identifier (hint: letters, digits, _)");
  return prefix;
}

/// The problem's sizes, names and gains; whether it has jerk rows.
void describe_problem(const Problem& problem, const SymbolicOptions& options, SymbolicReferenceDynamics::Impl& S) {
  const Model& model = problem.model;
  S.n = model.nq;
  S.cse = options.cse;
  S.nz = problem.forces.num_states();
  S.m = problem.constraints.rows();
  S.joints = model.joint_name;
  S.states = problem.forces.state_names();
  S.alpha = problem.options.alpha;
  S.beta = problem.options.beta;
  S.beta1 = problem.options.beta_first_order;
  S.kappa = problem.kappa;
  for (const auto& c : problem.constraints.constraints()) S.jerk = S.jerk || c->order() == 3;
}

/// The symbols: t, q, q̇, q̈, q⃛, the states z and the gains α, β, β₁, κ (under the GiNaC lock).
void make_symbols(const Model& model, SymbolicReferenceDynamics::Impl& S) {
  const int n = model.nq;
  S.t = GiNaC::realsymbol("t", "t");
  for (int i = 0; i < n; ++i) {
    const std::string k = std::to_string(i + 1);
    S.q.emplace_back("q(" + model.joint_name[i] + ")", "q_{" + k + "}");
    S.qd.emplace_back("qd(" + model.joint_name[i] + ")", "\\dot{q}_{" + k + "}");
  }
  for (int i = 0; i < n; ++i)
    S.qdd.emplace_back("qdd(" + model.joint_name[i] + ")", "\\ddot{q}_{" + std::to_string(i + 1) + "}");
  for (int i = 0; i < n; ++i)
    S.qddd.emplace_back("qddd(" + model.joint_name[i] + ")", "\\dddot{q}_{" + std::to_string(i + 1) + "}");
  for (int k = 0; k < S.nz; ++k) S.z.emplace_back("state(" + std::to_string(k) + ")", "z_{" + std::to_string(k + 1) + "}");
  S.alpha_s = GiNaC::realsymbol("rd_alpha", "\\alpha");
  S.beta_s = GiNaC::realsymbol("rd_beta", "\\beta");
  S.beta1_s = GiNaC::realsymbol("rd_beta1", "\\beta_1");
  S.kappa_s = GiNaC::realsymbol("rd_kappa", "\\kappa");
}

/// The model: as the scenario wrote it (parameters stay symbols), else the compiled numbers.
symbolic_detail::SymbolicModel symbolic_model_of(const Problem& problem, Binder& B, const std::vector<ex>& q) {
  const Model& model = problem.model;
  symbolic_detail::SymbolicBodies bodies;
  if (problem.model_numbers) {
    bodies = symbolic_detail::bodies_from_numbers(model, *problem.model_numbers, [&](const Quantity& v) {
      return B.parse(v.text, problem.parameters, "generate: " + v.where.file + ":" + std::to_string(v.where.line));
    });
  } else {
    bodies = multibody::bodies_from_model<GiNaC::ex>(model, symbolic_detail::CleanLift{});
  }
  return symbolic_detail::symbolic_model(bodies, model.gravity, q);
}

/// Binds the points' positions, velocities, accelerations (where an acceleration row may use
/// them), jerks (jerk problems) and orientations.
void bind_points(const Problem& problem, const SymbolicReferenceDynamics::Impl& S,
                 const symbolic_detail::SymbolicModel& sm, Binder& B) {
  const Model& model = problem.model;
  const int n = model.nq;
  bool acceleration_rows = false;
  for (const auto& c : problem.constraints.constraints()) acceleration_rows = acceleration_rows || c->order() >= 2;
  // the point jerk along the motion: d/dt of the acceleration with q̈ → q⃛
  GiNaC::exmap to_jerk;
  for (int i = 0; i < n; ++i) {
    to_jerk[S.q[i]] = S.qd[i];
    to_jerk[S.qd[i]] = S.qdd[i];
    to_jerk[S.qdd[i]] = S.qddd[i];
  }
  TotalRate point_jerk(to_jerk);
  // point velocities Σ ∂r/∂q_i q̇_i and accelerations d/dt of them along the motion (q → q̇,
  // q̇ → q̈), each node's rate once
  GiNaC::exmap to_velocity, to_acceleration;
  for (int i = 0; i < n; ++i) {
    to_velocity[S.q[i]] = S.qd[i];
    to_acceleration[S.q[i]] = S.qd[i];
    to_acceleration[S.qd[i]] = S.qdd[i];
  }
  TotalRate point_velocity(to_velocity), point_acceleration(to_acceleration);
  for (size_t p = 0; p < model.point_name.size(); ++p) {
    const int b = sm.bodies.points[p].body;
    const Vec3s r = multibody::point_position(sm.bodies.points[p], sm.poses);
    const symbolic_detail::Mat3s R = b < 0 ? multibody::identity3<ex>() : sm.poses.R[b];
    const std::string& P = model.point_name[p];
    static const char* axes[] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      const ex v = point_velocity(r[k]);
      B.bind(std::string(axes[k]) + "(" + P + ")", r[k]);
      B.bind(std::string("v") + axes[k] + "(" + P + ")", v);
      if (acceleration_rows) {  // point accelerations only where an acceleration row may use them
        const ex a = point_acceleration(v);
        B.bind(std::string("a") + axes[k] + "(" + P + ")", a);
        if (S.jerk) B.bind(std::string("j") + axes[k] + "(" + P + ")", point_jerk(a));
      }
    }
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) B.bind("R" + std::to_string(a + 1) + std::to_string(c + 1) + "(" + P + ")", R[3 * a + c]);
  }
}

/// The dynamics by Newton–Euler: c, g, M; then the jerk level, or the constraints' right-hand
/// sides (stabilized) of an acceleration-level problem.
void generate_dynamics(SymbolicReferenceDynamics::Impl& S, const symbolic_detail::SymbolicModel& sm,
                       const std::vector<ex>& qd) {
  S.model = sm;
  S.c = sm.inverse_dynamics(qd, {}, false);
  S.g = sm.inverse_dynamics({}, {}, true);
  S.M = multibody::mass_matrix(sm.bodies, sm.poses);

  if (S.jerk) {
    generate_jerk_level(S, sm);
  } else {
    S.cg = sm.inverse_dynamics(qd, {}, true);
    S.rhs.resize(S.m);
    for (int r = 0; r < S.m; ++r)
      S.rhs[r] = S.row_order[r] == 2 ? -S.gamma[r]
                 : S.row_order[r] == 1
                     ? -S.gamma[r] - S.beta1_s * S.phi[r]
                     : -S.gamma[r] - 2 * S.alpha_s * S.phid[r] - S.beta_s * S.beta_s * S.phi[r];
  }
}

/// The partition into independent and dependent coordinates (jerk problems: none, the jerk
/// level is solved as a KKT system).
void partition_coordinates(const Problem& problem, SymbolicReferenceDynamics::Impl& S) {
  const Model& model = problem.model;
  const int n = model.nq;
  std::vector<char> is_ind(n, 0);
  for (const std::string& name : problem.options.independent) is_ind[model.joint_index(name)] = 1;
  if (S.jerk) {
    for (int i = 0; i < n; ++i) S.independent.push_back(i);
  } else if (S.m > 0 && static_cast<int>(problem.options.independent.size()) != n - S.m)
    throw Error("generate: the partition names " + std::to_string(problem.options.independent.size()) +
                " independent coordinates, expected n − m = " + std::to_string(n - S.m));
  if (!S.jerk)
    for (int i = 0; i < n; ++i) (is_ind[i] || S.m == 0 ? S.independent : S.dependent).push_back(i);
}

}  // namespace

SymbolicReferenceDynamics generate_symbolic(const Problem& problem, const SymbolicOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (problem.options.paper_literal_forces)
    throw Error("generate: the paper-literal force option (forces: paper_literal) has no generated form "
                "(hint: remove it; the generated equations use Lagrange's forces)");
  auto impl = std::make_shared<SymbolicReferenceDynamics::Impl>();
  SymbolicReferenceDynamics::Impl& S = *impl;
  const Model& model = problem.model;
  S.name = problem.name;
  S.prefix = symbol_prefix(problem, options);
  describe_problem(problem, options, S);

  std::lock_guard<std::mutex> lock(expr_detail::ginac_mutex());
  make_symbols(model, S);
  std::vector<ex> q(S.q.begin(), S.q.end()), qd(S.qd.begin(), S.qd.end());

  // --- variables of the expression language ---
  Binder B(S);
  B.bind("t", S.t);
  B.bind("deg", GiNaC::Pi / 180);  // exact: cos(90*deg) is 0, not 6e-17
  const symbolic_detail::SymbolicModel sm = symbolic_model_of(problem, B, q);
  for (int i = 0; i < S.n; ++i) {
    B.bind("q(" + model.joint_name[i] + ")", S.q[i]);
    B.bind("qd(" + model.joint_name[i] + ")", S.qd[i]);
    B.bind("qdd(" + model.joint_name[i] + ")", S.qdd[i]);
    if (S.jerk) B.bind("qddd(" + model.joint_name[i] + ")", S.qddd[i]);
  }
  bind_points(problem, S, sm, B);

  generate_constraints(problem, S, B);
  generate_forces(problem, S, B);
  generate_dynamics(S, sm, qd);
  partition_coordinates(problem, S);

  S.summary.nq = S.n;
  S.summary.nz = S.nz;
  S.summary.constraints = S.m;
  S.summary.parameters = static_cast<int>(S.params.size());
  S.summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return SymbolicReferenceDynamics(impl);
}

}  // namespace refdyn
