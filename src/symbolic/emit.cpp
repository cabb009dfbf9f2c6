// Writers of the generated reference dynamics as LaTeX and JSON (the C writer is emit_c.cpp;
// both print from the canonical graph of tape.hpp).
#include "internal.hpp"
#include "printer.hpp"
#include "tape.hpp"

#include "refdyn/common/json.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>

namespace refdyn {

using GiNaC::ex;
using GiNaC::is_a;
using symbolic_detail::double_text;

// ----------------------------------------------------------------------------------------------
const std::string& SymbolicReferenceDynamics::prefix() const { return impl_->prefix; }
const SymbolicSummary& SymbolicReferenceDynamics::summary() const { return impl_->summary; }

// ----------------------------------------------------------------------------------------------
// LaTeX
// ----------------------------------------------------------------------------------------------
namespace {


std::string latex_text(const std::string& s) {
  std::string r;
  for (char ch : s) {
    if (ch == '_' || ch == '&' || ch == '%' || ch == '$' || ch == '#' || ch == '{' || ch == '}') r += std::string("\\") + ch;
    else if (ch == '\\') r += "\\textbackslash{}";
    else if (ch == '^') r += "\\^{}";
    else if (ch == '~') r += "\\~{}";
    else r += ch;
  }
  return r;
}


/// The LaTeX of the displayed expressions, through the canonical tape (tape.hpp): the same
/// text in every run. Shared sub-expressions that are not short, and long ones, become
/// auxiliary quantities u_k, numbered in the order they are first printed; sin q_i, cos q_i are
/// written s_i, c_i.
class LatexWriter {
 public:
  /// `shown`: every expression the document displays (for counting shared sub-expressions).
  LatexWriter(const SymbolicReferenceDynamics::Impl& S, const std::vector<ex>& shown)
      : scope_(tape_), conv_(tape_, [](const GiNaC::symbol& s) { return s.get_TeX_name(); }, true) {
    for (int i = 0; i < S.n; ++i) qindex_[S.q[i].get_TeX_name()] = i + 1;
    std::vector<int> roots;
    for (const ex& e : shown) roots.push_back(conv_(e));
    uses_.assign(tape_.size(), 0);
    for (int r : roots) count(r);
  }
  /// "lhs &= rhs \\" with a line break every ~140 characters of a long top-level sum.
  std::string equation(const std::string& lhs, const ex& e) {
    const int id = conv_(e);
    grow();
    std::vector<std::pair<bool, int>> terms;  // (negative, term) of the top-level sum
    flatten(id, false, terms);
    std::string body;
    if (terms.size() > 3) {
      std::size_t width = 0;
      for (size_t i = 0; i < terms.size(); ++i) {
        const auto [neg, t] = terms[i];
        const std::string term = operand(t, 1);
        if (i > 0 && width + term.size() > 140) {
          body += " \\\\\n  &\\quad";
          width = 0;
        }
        body += (i == 0 ? (neg ? "-" : "") : (neg ? " - " : " + ")) + term;
        width += term.size() + 3;
      }
    } else {
      body = node_text(id);
    }
    return "  " + lhs + " &= " + body + " \\\\\n";
  }
  /// The auxiliary quantities u_k the printed equations use, defined in order.
  std::string definitions() {
    std::string out;
    for (std::size_t k = 0; k < defs_.size(); ++k) out += "  u_{" + std::to_string(k + 1) + "} &= " + defs_[k] + " \\\\\n";
    return out;
  }
  std::size_t size() const { return defs_.size(); }

 private:
  using Op = symbolic_detail::Tape::Op;
  const symbolic_detail::Tape::Node& N(int id) const { return tape_.node(id); }
  void grow() {
    if (uses_.size() < tape_.size()) uses_.resize(tape_.size(), 1);
  }
  void count(int id) {
    if (uses_[id]++ > 0) return;
    for (int a : N(id).args) count(a);
  }
  void flatten(int id, bool neg, std::vector<std::pair<bool, int>>& out) {
    const auto& n = N(id);
    if (n.op == Op::Add && !(N(n.args[1]).op == Op::Const && N(n.args[1]).value < 0) &&
        !(N(n.args[0]).op == Op::Const && N(n.args[0]).value < 0)) {
      flatten(n.args[0], neg, out);
      flatten(n.args[1], neg, out);
    } else if (n.op == Op::Sub) {
      flatten(n.args[0], neg, out);
      flatten(n.args[1], !neg, out);
    } else if (n.op == Op::Neg) {
      flatten(n.args[0], !neg, out);
    } else {
      out.emplace_back(neg, id);
    }
  }
  static std::string number(double v) {
    std::string s = double_text(std::fabs(v), 6);
    const auto e = s.find('e');
    if (e != std::string::npos) s = s.substr(0, e) + " \\cdot 10^{" + std::to_string(std::stoi(s.substr(e + 1))) + "}";
    return v < 0 ? "-" + s : s;
  }
  /// sin(q_i), cos(q_i) → s_i, c_i
  std::string trig(int id) const {
    const auto& n = N(id);
    if (n.op != Op::Call || n.args.size() != 1 || N(n.args[0]).op != Op::Leaf) return "";
    const auto it = qindex_.find(N(n.args[0]).text);
    if (it == qindex_.end()) return "";
    if (n.text == "sin") return "s_{" + std::to_string(it->second) + "}";
    if (n.text == "cos") return "c_{" + std::to_string(it->second) + "}";
    return "";
  }
  /// A node where it is used: its auxiliary name, or its text (which may make it one).
  std::string print(int id) {
    const auto a = aux_.find(id);
    if (a != aux_.end()) return a->second;
    const auto& n = N(id);
    if (n.op == Op::Const || n.op == Op::Leaf) return node_text(id);
    const std::string abbreviation = trig(id);
    if (!abbreviation.empty()) return abbreviation;
    const std::string text = node_text(id);
    grow();
    if ((uses_[id] >= 2 && text.size() >= 40) || text.size() >= 300) {
      defs_.push_back(text);
      const std::string name = "u_{" + std::to_string(defs_.size()) + "}";
      aux_.emplace(id, name);
      return name;
    }
    return text;
  }
  /// print(id) as an operand: level 1 right of −, 2 factor, 4 base of a power.
  std::string operand(int id, int level) {
    const std::string s = print(id);
    if (aux_.count(id) || !trig(id).empty()) return s;
    const auto& n = N(id);
    const bool low = ((n.op == Op::Add || n.op == Op::Sub) && level >= 1) ||
                     ((n.op == Op::Neg || (n.op == Op::Const && n.value < 0)) && level >= 2) ||
                     ((n.op == Op::Mul || n.op == Op::Div || n.op == Op::Pow) && level >= 4);
    return low ? "\\left(" + s + "\\right)" : s;
  }
  std::string node_text(int id) {
    const auto m = memo_.find(id);
    if (m != memo_.end()) return m->second;
    const auto& n = N(id);
    std::string s;
    switch (n.op) {
      case Op::Const: s = number(n.value); break;
      case Op::Leaf: s = n.text == "pi" ? "\\pi" : n.text; break;
      case Op::Add: {
        int a = n.args[0], b = n.args[1];
        if (N(a).op == Op::Const) std::swap(a, b);
        if (N(b).op == Op::Const && N(b).value < 0) s = print(a) + " - " + number(-N(b).value);
        else s = print(a) + " + " + operand(b, 0);
        break;
      }
      case Op::Sub: s = print(n.args[0]) + " - " + operand(n.args[1], 1); break;
      case Op::Mul: s = operand(n.args[0], 2) + " " + operand(n.args[1], 2); break;
      case Op::Div: s = "\\frac{" + print(n.args[0]) + "}{" + print(n.args[1]) + "}"; break;
      case Op::Neg: s = "-" + operand(n.args[0], 2); break;
      case Op::Pow: s = "{" + operand(n.args[0], 4) + "}^{" + number(n.value) + "}"; break;
      case Op::Cond:
        s = "\\begin{cases}" + print(n.args[2]) + " & " + print(n.args[0]) + (n.value != 0 ? " < " : " \\le ") +
            print(n.args[1]) + "\\\\ " + print(n.args[3]) + " & \\text{otherwise}\\end{cases}";
        break;
      case Op::Call: {
        const std::string abbreviation = trig(id);
        if (!abbreviation.empty()) {
          s = abbreviation;
          break;
        }
        std::vector<std::string> a;
        for (int x : n.args) a.push_back(print(x));
        auto call = [&](const std::string& name) {
          std::string r = name + "\\left(";
          for (size_t i = 0; i < a.size(); ++i) r += (i ? ", " : "") + a[i];
          return r + "\\right)";
        };
        const std::string& f = n.text;
        static const std::map<std::string, std::string> names = {
            {"sin", "\\sin"},     {"cos", "\\cos"},       {"tan", "\\tan"},       {"sinh", "\\sinh"},
            {"cosh", "\\cosh"},   {"tanh", "\\tanh"},     {"exp", "\\exp"},       {"log", "\\log"},
            {"asin", "\\arcsin"}, {"acos", "\\arccos"},   {"atan", "\\arctan"},   {"rd_min", "\\min"},
            {"rd_max", "\\max"},  {"rd_sgn", "\\operatorname{sgn}"}, {"rd_step", "\\operatorname{step}"},
            {"rd_clamp", "\\operatorname{clamp}"}};
        if (f == "sqrt") s = "\\sqrt{" + a[0] + "}";
        else if (f == "fabs") s = "\\left|" + a[0] + "\\right|";
        else if (f == "pow") s = "{" + operand(n.args[0], 4) + "}^{" + a[1] + "}";
        else if (names.count(f)) s = call(names.at(f));
        else s = call("\\operatorname{" + latex_text(f) + "}");
        break;
      }
    }
    memo_.emplace(id, s);
    return s;
  }

  symbolic_detail::Tape tape_;
  symbolic_detail::TapeScope scope_;
  symbolic_detail::FromGinac conv_;
  std::map<std::string, int> qindex_;
  std::vector<int> uses_;
  std::map<int, std::string> aux_, memo_;
  std::vector<std::string> defs_;
};

/// The document's head, the coordinates and the parameters.
void latex_preamble(std::ostream& o, const SymbolicReferenceDynamics::Impl& S) {
  const int n = S.n;
  o << "% Reference dynamics of '" << S.name << "', generated by refdyn (refdyn generate).\n"
    << "\\documentclass[10pt]{article}\n\\usepackage{amsmath}\n"
    << "\\setlength{\\textwidth}{17cm}\\setlength{\\oddsidemargin}{-0.5cm}\\setlength{\\textheight}{24cm}"
    << "\\setlength{\\topmargin}{-1.5cm}\n\\allowdisplaybreaks\n"
    << "\\title{Reference dynamics of \\texttt{" << latex_text(S.name) << "}}\n\\author{generated by refdyn}\n\\date{}\n"
    << "\\begin{document}\n\\maketitle\n\n";
  o << "\\section*{Coordinates and parameters}\n"
    << "Generalized coordinates $q = (q_1, \\dots, q_{" << n << "})$ (joints in this order):\n\\begin{center}\n"
    << "\\begin{tabular}{ll}\n\\hline coordinate & joint \\\\ \\hline\n";
  for (int i = 0; i < n; ++i) o << "$q_{" << i + 1 << "}$ & \\texttt{" << latex_text(S.joints[i]) << "} \\\\\n";
  o << "\\hline\n\\end{tabular}\n\\end{center}\n"
    << "Abbreviations: $s_i = \\sin q_i$, $c_i = \\cos q_i$. Numbers are shown to 6 significant digits (the C and JSON "
    << "outputs carry them exactly).";
  if (S.nz) {
    o << " Force-element states:";
    for (int k = 0; k < S.nz; ++k) o << " $z_{" << k + 1 << "}$ = \\texttt{" << latex_text(S.states[k]) << "}" << (k + 1 < S.nz ? "," : ".");
  }
  o << "\n\n";
  if (!S.param_names.empty()) {
    o << "Parameters (kept symbolic; scenario values):\n\\begin{center}\n\\begin{tabular}{ll}\n\\hline name & value \\\\ \\hline\n";
    for (size_t k = 0; k < S.param_names.size(); ++k)
      o << "$" << S.params[k].get_TeX_name() << "$ & " << double_text(S.param_values[k], 17) << " \\\\\n";
    o << "\\hline\n\\end{tabular}\n\\end{center}\n\n";
  }
}

/// The equations the printed expressions belong to: the jerk level's KKT system, or the
/// constraints merged into the reference dynamics.
void latex_equations(std::ostream& o, const SymbolicReferenceDynamics::Impl& S) {
  const int m = S.m;
  if (S.jerk) {
    o << "\\section*{Equations}\nA problem with jerk rows: the state is $x = (q, \\dot q, \\ddot q, z)$ and "
      << "$\\dot x = (\\dot q, \\ddot q, \\dddot q, \\dot z)$. With the dynamics residual\n"
      << "\\begin{align*}\n  R &= M(q)\\,\\ddot q + c(q,\\dot q) + g(q) - Q(t,q,\\dot q,z),\n\\end{align*}\n"
      << "every jerk row $B(t,q,\\dot q)\\,\\dddot q + s(t,q,\\dot q,\\ddot q) = 0$ is imposed as $B\\dddot q = -s$, and "
      << "every row of order $\\le 2$ in its stabilized acceleration form\n"
      << "\\begin{align*}\n  \\psi &= A\\ddot q + \\gamma + 2\\alpha\\dot\\Phi + \\beta^2\\Phi \\quad\\text{(position rows)}, "
      << "\\qquad \\psi = A\\ddot q + \\gamma + \\beta_1 c \\quad\\text{(velocity rows)}, \\qquad "
      << "\\psi = A\\ddot q + \\gamma \\quad\\text{(acceleration rows)}\n\\end{align*}\n"
      << "as $\\dot\\psi + \\kappa\\psi = 0$, i.e.\\ $A\\dddot q = -\\dot\\psi|_{\\dddot q = 0} - \\kappa\\psi$. "
      << "Stacked: $G\\dddot q = b$ ($G$: the rows $A$ and $B$). The jerk of the motion solves\n"
      << "\\begin{align*}\n  \\begin{pmatrix} M & -G^{\\mathsf T} \\\\ G & 0 \\end{pmatrix}"
      << "\\begin{pmatrix} \\dddot q \\\\ \\nu \\end{pmatrix} &= "
      << "\\begin{pmatrix} \\dot G^{\\mathsf T}\\lambda - \\dot R|_{\\dddot q = 0} - \\kappa R \\\\ b \\end{pmatrix}, "
      << "\\qquad \\lambda = \\bigl(G M^{-1} G^{\\mathsf T}\\bigr)^{-1} G M^{-1} R,\n\\end{align*}\n"
      << "where the rates are total time derivatives along the motion with $\\dddot q = 0$; "
      << "$\\alpha = " << double_text(S.alpha, 6) << "$, $\\beta = " << double_text(S.beta, 6) << "$, $\\beta_1 = "
      << double_text(S.beta1, 6) << "$, $\\kappa = " << double_text(S.kappa, 6) << "$.\n\n";
  } else {
    o << "\\section*{Equations}\nThe unconstrained dynamics and the constraints,\n"
      << "\\begin{align*}\n  M(q)\\,\\ddot q + c(q,\\dot q) + g(q) &= Q(t,q,\\dot q,z) + A^{\\mathsf T}\\lambda, \\\\\n"
      << "  A\\,\\ddot q &= -\\gamma - 2\\alpha\\dot\\Phi - \\beta^2\\Phi \\quad\\text{(position rows)}, \\qquad "
      << "A\\,\\ddot q = -\\gamma - \\beta_1 c \\quad\\text{(velocity rows)}, \\qquad "
      << "A\\,\\ddot q = -\\gamma \\quad\\text{(acceleration rows)},\n\\end{align*}\n"
      << "with $\\alpha = " << double_text(S.alpha, 6) << "$, $\\beta = " << double_text(S.beta, 6) << "$, $\\beta_1 = "
      << double_text(S.beta1, 6) << "$ (Baumgarte), are merged into the reference dynamics\n";
    if (m > 0) {
      auto idx = [](const std::vector<int>& v) {
        std::string s;
        for (size_t i = 0; i < v.size(); ++i)
          s += (i ? ", " : "") + std::string("q_{") + std::to_string(v[i] + 1) + "}";
        return s;
      };
      o << "\\begin{align*}\n  N^{\\mathsf T}\\bigl(M\\ddot q + c + g - Q\\bigr) &= 0, \\qquad "
        << "N = \\frac{\\partial \\dot q}{\\partial \\dot q_{ic}} = "
        << "\\begin{pmatrix} I \\\\ -K_{dc}^{-1}K_{ic}\\end{pmatrix},\n"
        << "\\end{align*}\n"
        << "in the independent coordinates $q_{ic} = (" << idx(S.independent)
        << ")$ with the dependent ones $q_{dc} = ("
        << idx(S.dependent) << ")$; $K_{ic}$ and $K_{dc}$ are the columns of $A$ of $q_{ic}$ and $q_{dc}$ "
        << "(rows of $N$ in the order $q_{ic}, q_{dc}$).\n\n";
    } else {
      o << "$M\\ddot q + c + g = Q$ (no constraints).\n\n";
    }
  }
}

/// The mass matrix, c, g, Q and ż.
void latex_dynamics(std::ostream& o, const SymbolicReferenceDynamics::Impl& S, LatexWriter& w) {
  const int n = S.n;
  o << "\\section*{Mass matrix $M(q)$ (symmetric; upper triangle)}\n\\begin{align*}\n";
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j)
      if (!S.M[i * n + j].is_zero()) o << w.equation("M_{" + std::to_string(i + 1) + std::to_string(j + 1) + "}", S.M[i * n + j]);
  o << "\\end{align*}\n\\section*{Velocity products $c(q, \\dot q)$ and gravity $g(q)$}\n\\begin{align*}\n";
  for (int i = 0; i < n; ++i) o << w.equation("c_{" + std::to_string(i + 1) + "}", S.c[i]);
  for (int i = 0; i < n; ++i) o << w.equation("g_{" + std::to_string(i + 1) + "}", S.g[i]);
  o << "\\end{align*}\n\\section*{Generalized forces $Q$}\n\\begin{align*}\n";
  for (int i = 0; i < n; ++i) o << w.equation("Q_{" + std::to_string(i + 1) + "}", S.Q[i]);
  for (int k = 0; k < S.nz; ++k) o << w.equation("\\dot z_{" + std::to_string(k + 1) + "}", S.zdot[k]);
  o << "\\end{align*}\n";
}

/// Each constraint row: Φ (or c), Φ̇, A and γ.
void latex_constraints(std::ostream& o, const SymbolicReferenceDynamics::Impl& S, LatexWriter& w) {
  const int n = S.n, m = S.m;
  o << "\\section*{Constraints}\n";
  for (int r = 0; r < m; ++r) {
    const std::string R = std::to_string(r + 1);
    o << "\\paragraph{Row " << R << ": \\texttt{" << latex_text(S.row_names[r]) << "}} (" << S.row_origin[r] << ", "
      << (S.row_order[r] == 3 ? "jerk level: $B\\dddot q + s = 0$, imposed exactly; $B$ and $s$ shown as $A$ and $\\gamma$"
          : S.row_order[r] == 2 ? "acceleration level: $A\\ddot q + \\gamma = 0$, imposed exactly"
                              : S.row_order[r] == 1 ? "velocity level" : "position level")
      << ")\n\\begin{align*}\n";
    if (S.row_order[r] < 2) o << w.equation(S.row_order[r] ? "c_{" + R + "}" : "\\Phi_{" + R + "}", S.phi[r]);
    if (S.row_order[r] == 0) o << w.equation("\\dot\\Phi_{" + R + "}", S.phid[r]);
    for (int i = 0; i < n; ++i)
      if (!S.A[r * n + i].is_zero()) o << w.equation("A_{" + R + "," + std::to_string(i + 1) + "}", S.A[r * n + i]);
    o << w.equation("\\gamma_{" + R + "}", S.gamma[r]) << "\\end{align*}\n";
  }
}

/// The jerk level: R, Ṙ and per row Ġ, ψ and b.
void latex_jerk_level(std::ostream& o, const SymbolicReferenceDynamics::Impl& S, LatexWriter& w) {
  const int n = S.n, m = S.m;
  o << "\\section*{Jerk level}\nThe dynamics residual $R$ and its rate at $\\dddot q = 0$,\n\\begin{align*}\n";
  for (int i = 0; i < n; ++i) o << w.equation("R_{" + std::to_string(i + 1) + "}", S.R[i]);
  for (int i = 0; i < n; ++i) o << w.equation("\\dot R_{" + std::to_string(i + 1) + "}", S.Rdot[i]);
  o << "\\end{align*}\n";
  for (int r = 0; r < m; ++r) {
    const std::string R = std::to_string(r + 1);
    o << "\\paragraph{Row " << R << " at jerk level} ($G_{" << R << "} = A_{" << R << "}$; $\\dot G$, "
      << (S.row_order[r] == 3 ? "$b = -s$" : "$\\psi$ and $b = -\\dot\\psi|_{\\dddot q = 0} - \\kappa\\psi$")
      << ")\n\\begin{align*}\n";
    for (int i = 0; i < n; ++i)
      if (!S.Gdot[r * n + i].is_zero())
        o << w.equation("\\dot G_{" + R + "," + std::to_string(i + 1) + "}", S.Gdot[r * n + i]);
    if (S.row_order[r] < 3) o << w.equation("\\psi_{" + R + "}", S.psi[r]);
    o << w.equation("b_{" + R + "}", S.b[r]) << "\\end{align*}\n";
  }
}

}  // namespace

std::string SymbolicReferenceDynamics::latex() const {
  const Impl& S = *impl_;
  std::vector<ex> shown;
  for (const auto* v : {&S.M, &S.c, &S.g, &S.Q, &S.zdot, &S.phi, &S.phid, &S.A, &S.gamma, &S.R, &S.Rdot, &S.Gdot, &S.psi, &S.b})
    shown.insert(shown.end(), v->begin(), v->end());
  std::lock_guard<std::mutex> lock(expr_detail::ginac_mutex());
  LatexWriter w(S, shown);
  std::ostringstream o;
  latex_preamble(o, S);
  latex_equations(o, S);
  const std::size_t equations_at = static_cast<std::size_t>(o.tellp());
  latex_dynamics(o, S, w);
  if (S.m > 0) latex_constraints(o, S, w);
  if (S.jerk) latex_jerk_level(o, S, w);
  o << "\\end{document}\n";
  std::string text = o.str();
  if (w.size() > 0)
    text.insert(equations_at, "\\section*{Auxiliary quantities}\nShared or long sub-expressions, named once and used below.\n"
                              "\\begin{align*}\n" + w.definitions() + "\\end{align*}\n");
  return text;
}

// ----------------------------------------------------------------------------------------------
// JSON
// ----------------------------------------------------------------------------------------------
std::string SymbolicReferenceDynamics::json() const {
  const Impl& S = *impl_;
  const int n = S.n, m = S.m;
  // through the canonical tape (tape.hpp): the same text in every run
  std::lock_guard<std::mutex> lock(expr_detail::ginac_mutex());
  symbolic_detail::Tape tape;
  symbolic_detail::TapeScope scope(tape);
  symbolic_detail::FromGinac conv(tape, [](const GiNaC::symbol& s) { return s.get_name(); }, true);
  // Two passes over the same sequence of expressions: the first puts them on the tape, the
  // second prints them with auxiliaries aux(k) for the shared or long sub-expressions.
  std::vector<int> roots;
  std::size_t next = 0;
  std::unique_ptr<symbolic_detail::AuxiliaryTexts> texts;
  auto str = [&](const ex& e) -> std::string {
    if (!texts) {
      roots.push_back(conv(e));
      return std::string();
    }
    return json_quote((*texts)(roots.at(next++)));
  };
  auto ints = [](const std::vector<int>& v) {
    std::string s = "[";
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    return s + "]";
  };
  std::ostringstream o;
  o << "{\n  \"generator\": \"refdyn generate\",\n  \"name\": " << json_quote(S.name) << ",\n"
    << "  \"syntax\": \"refdyn expression language: q(j), qd(j) joint coordinates and velocities, state(k) force-element "
       "states, t time, named parameters, aux(k) the k-th entry of auxiliaries (shared sub-expressions, each naming only "
       "earlier ones)\",\n"
    << "  \"joints\": [";
  for (int i = 0; i < n; ++i) o << (i ? ", " : "") << json_quote(S.joints[i]);
  o << "],\n  \"states\": [";
  for (int k = 0; k < S.nz; ++k) o << (k ? ", " : "") << json_quote(S.states[k]);
  o << "],\n  \"parameters\": {";
  for (size_t k = 0; k < S.param_names.size(); ++k)
    o << (k ? ", " : "") << json_quote(S.param_names[k]) << ": " << double_text(S.param_values[k], 17);
  o << "},\n  \"baumgarte\": {\"alpha\": " << double_text(S.alpha, 17) << ", \"beta\": " << double_text(S.beta, 17)
    << ", \"beta_first_order\": " << double_text(S.beta1, 17) << "},\n"
    << "  \"independent\": " << ints(S.independent) << ",\n  \"dependent\": " << ints(S.dependent) << ",\n";
  const std::string head = o.str();
  auto body = [&](std::ostringstream& o) {
    o << "  \"M\": [";
    for (int i = 0; i < n; ++i) {
      o << (i ? ",\n        [" : "[");
      for (int j = 0; j < n; ++j) o << (j ? ", " : "") << str(S.M[i * n + j]);
      o << "]";
    }
    o << "],\n  \"c\": [";
    for (int i = 0; i < n; ++i) o << (i ? ", " : "") << str(S.c[i]);
    o << "],\n  \"g\": [";
    for (int i = 0; i < n; ++i) o << (i ? ", " : "") << str(S.g[i]);
    o << "],\n  \"Q\": [";
    for (int i = 0; i < n; ++i) o << (i ? ", " : "") << str(S.Q[i]);
    o << "],\n  \"zdot\": [";
    for (int k = 0; k < S.nz; ++k) o << (k ? ", " : "") << str(S.zdot[k]);
    o << "],\n  \"constraints\": [";
    for (int r = 0; r < m; ++r) {
      o << (r ? ",\n" : "\n") << "    {\"name\": " << json_quote(S.row_names[r]) << ", \"origin\": " << json_quote(S.row_origin[r])
        << ", \"order\": " << (S.row_order[r] == 3 ? "\"jerk\"" : S.row_order[r] == 2 ? "\"acceleration\"" : S.row_order[r] ? "\"velocity\"" : "\"position\"")
        << ",\n     \"phi\": " << str(S.phi[r])
        << ",\n     \"phid\": " << str(S.phid[r]) << ",\n     \"A\": [";
      for (int i = 0; i < n; ++i) o << (i ? ", " : "") << str(S.A[r * n + i]);
      o << "],\n     \"gamma\": " << str(S.gamma[r]) << "}";
    }
    o << (m ? "\n  " : "") << "]";
    if (S.jerk) {
      // the gains appear as rd_alpha, rd_beta, rd_beta1, rd_kappa (fields of the C parameters)
      auto list = [&](const std::vector<ex>& v, int from, int count) {
        std::string t = "[";
        for (int i = 0; i < count; ++i) t += (i ? ", " : "") + str(v[from + i]);
        return t + "]";
      };
      o << ",\n  \"jerk\": {\"kappa\": " << double_text(S.kappa, 17) << ",\n    \"R\": " << list(S.R, 0, n)
        << ",\n    \"Rdot\": " << list(S.Rdot, 0, n) << ",\n    \"rows\": [";
      for (int r = 0; r < m; ++r)
        o << (r ? ",\n" : "\n") << "      {\"Gdot\": " << list(S.Gdot, r * n, n) << ",\n       \"psi\": " << str(S.psi[r])
          << ",\n       \"b\": " << str(S.b[r]) << "}";
      o << (m ? "\n    " : "") << "]}";
    }
    o << "\n}\n";
  };
  {
    std::ostringstream first;
    body(first);
  }
  texts = std::make_unique<symbolic_detail::AuxiliaryTexts>(tape, roots);
  std::ostringstream rest;
  body(rest);
  std::string out = head + "  \"auxiliaries\": [";
  const auto& aux = texts->auxiliaries();
  for (std::size_t k = 0; k < aux.size(); ++k) out += (k ? ",\n    " : "\n    ") + json_quote(aux[k]);
  out += aux.empty() ? "],\n" : "\n  ],\n";
  return out + rest.str();
}

}  // namespace refdyn
