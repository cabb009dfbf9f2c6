// Writers of the generated reference dynamics: C99 (with common-subexpression elimination),
// LaTeX and JSON. One printer over GiNaC expressions with three dialects.
#include "internal.hpp"

#include "../expression/internal.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <sstream>

namespace refdyn {

using GiNaC::ex;
using GiNaC::is_a;

namespace {

enum class Dialect { C, Latex, Text };

std::string double_text(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  std::string s = buf;
  return s;
}

/// Prints GiNaC expressions. `leaf` names symbols; `shared` (C only) returns the name of a
/// common sub-expression or an empty string.
class Printer {
 public:
  Printer(Dialect d, std::function<std::string(const GiNaC::symbol&)> leaf) : d_(d), leaf_(std::move(leaf)) {}
  std::function<std::string(const ex&)> shared;  // C: temporaries
  long operations = 0;

  /// A term printed with a leading minus (negative number, or product with a negative coefficient).
  static bool negative_term(const ex& t) {
    if (is_a<GiNaC::numeric>(t)) return GiNaC::ex_to<GiNaC::numeric>(t).is_negative();
    if (is_a<GiNaC::mul>(t)) {
      const ex c = t.op(t.nops() - 1);
      return is_a<GiNaC::numeric>(c) && GiNaC::ex_to<GiNaC::numeric>(c).is_negative();
    }
    return false;
  }
  /// Texts of nodes already printed (LaTeX: printing a shared graph once per node).
  std::map<ex, std::string, GiNaC::ex_is_less>* memo = nullptr;

  std::string print(const ex& e) {
    if (shared) {
      const std::string s = shared(e);
      if (!s.empty()) return s;
    }
    if (memo) {
      const auto it = memo->find(e);
      if (it != memo->end()) return it->second;
    }
    std::string text = print_node(e);
    if (memo && !is_a<GiNaC::symbol>(e) && !is_a<GiNaC::numeric>(e)) memo->emplace(e, text);
    return text;
  }
  /// The node itself (children through print()).
  std::string print_node(const ex& e) {
    if (is_a<GiNaC::numeric>(e)) return number(GiNaC::ex_to<GiNaC::numeric>(e));
    if (is_a<GiNaC::symbol>(e)) return leaf_(GiNaC::ex_to<GiNaC::symbol>(e));
    if (is_a<GiNaC::constant>(e)) {
      if (d_ == Dialect::Latex) return "\\pi";
      if (d_ == Dialect::Text) return "pi";
      return double_text(GiNaC::ex_to<GiNaC::numeric>(e.evalf()).to_double(), 17);
    }
    if (is_a<GiNaC::add>(e)) return sum(e);
    if (is_a<GiNaC::mul>(e)) return product(e);
    if (is_a<GiNaC::power>(e)) return power(e.op(0), e.op(1));
    if (is_a<GiNaC::function>(e)) return function(e);
    throw Error("generate: cannot print the expression " + expr_detail::to_text(e));
  }

 private:
  std::string number(const GiNaC::numeric& x) {
    std::string s;
    if (x.is_integer() && GiNaC::abs(x) < GiNaC::numeric(1L << 52)) {
      s = std::to_string(x.to_long());
      if (d_ == Dialect::C) s += ".0";
    } else if (x.is_rational() && d_ == Dialect::Latex) {
      const GiNaC::numeric a = GiNaC::abs(x);
      s = "\\tfrac{" + std::to_string(a.numer().to_long()) + "}{" + std::to_string(a.denom().to_long()) + "}";
      if (x.is_negative()) s = "-" + s;
    } else {
      s = double_text(x.to_double(), d_ == Dialect::Latex ? 6 : 17);
      if (d_ == Dialect::Latex) {
        const auto e = s.find('e');
        if (e != std::string::npos) s = s.substr(0, e) + " \\cdot 10^{" + std::to_string(std::stoi(s.substr(e + 1))) + "}";
      }
    }
    return x.is_negative() && d_ != Dialect::Latex ? "(" + s + ")" : s;
  }
  /// e as an operand of a product or power: parenthesised unless atomic.
  /// in_product: a power needs no parentheses as a factor of a product (it binds tighter).
  std::string factor(const ex& e, bool in_product = false) {
    const std::string s = print(e);
    const bool atomic = is_a<GiNaC::symbol>(e) || is_a<GiNaC::function>(e) || is_a<GiNaC::constant>(e) ||
                        (is_a<GiNaC::numeric>(e) && !GiNaC::ex_to<GiNaC::numeric>(e).is_negative()) ||
                        (shared && !shared(e).empty()) ||
                        ((d_ == Dialect::C || in_product) && is_a<GiNaC::power>(e));
    if (atomic) return s;
    return d_ == Dialect::Latex ? "\\left(" + s + "\\right)" : "(" + s + ")";
  }
  std::string sum(const ex& e) {
    std::string s;
    for (size_t i = 0; i < e.nops(); ++i) {
      const ex t = e.op(i);
      const bool neg = negative_term(t);
      const std::string body = print(neg ? ex(-t) : t);
      if (i == 0) s = neg ? "-" + body : body;
      else s += (neg ? " - " : " + ") + body;
      if (i) ++operations;
    }
    return s;
  }
  std::string product(const ex& e) {
    std::vector<std::string> num, den;
    std::string sign;
    for (size_t i = 0; i < e.nops(); ++i) {
      const ex f = e.op(i);
      if (is_a<GiNaC::numeric>(f)) {
        GiNaC::numeric c = GiNaC::ex_to<GiNaC::numeric>(f);
        if (c.is_negative()) {
          sign = "-";
          c = -c;
        }
        if (c.is_equal(1)) continue;
        if (c.is_rational() && !c.is_integer() && d_ != Dialect::Latex) {
          if (!c.numer().is_equal(1)) num.push_back(number(c.numer()));
          den.push_back(number(c.denom()));
        } else {
          num.insert(num.begin(), number(c));
        }
        continue;
      }
      if (is_a<GiNaC::power>(f) && is_a<GiNaC::numeric>(f.op(1)) &&
          GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_negative() && !(shared && !shared(f).empty())) {
        const ex inv = GiNaC::power(f.op(0), -f.op(1)).hold();
        den.push_back(GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_equal(-1) ? factor(f.op(0), true) : factor(inv, true));
        if (!GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_equal(-1)) ++operations;
        continue;
      }
      num.push_back(factor(f, true));
    }
    const std::string times = d_ == Dialect::Latex ? " " : "*";
    auto join = [&](const std::vector<std::string>& v) {
      std::string s;
      for (size_t i = 0; i < v.size(); ++i) s += (i ? times : "") + v[i];
      if (v.size() > 1) operations += static_cast<long>(v.size()) - 1;
      return s;
    };
    std::string n = num.empty() ? (d_ == Dialect::C ? "1.0" : "1") : join(num);
    if (den.empty()) return sign + n;
    ++operations;
    const std::string d = join(den);
    if (d_ == Dialect::Latex) return sign + "\\frac{" + n + "}{" + d + "}";
    return sign + (num.size() > 1 ? "(" + n + ")" : n) + "/" + (den.size() > 1 ? "(" + d + ")" : d);
  }
  std::string power(const ex& b, const ex& p) {
    ++operations;
    if (p.is_equal(GiNaC::numeric(1, 2))) return d_ == Dialect::Latex ? "\\sqrt{" + print(b) + "}" : "sqrt(" + print(b) + ")";
    if (p.is_equal(GiNaC::numeric(-1, 2)))
      return d_ == Dialect::Latex ? "\\frac{1}{\\sqrt{" + print(b) + "}}" : (d_ == Dialect::C ? "1.0/" : "1/") + std::string("sqrt(") + print(b) + ")";
    if (d_ == Dialect::C) {
      if (p.is_equal(-1)) return "1.0/" + factor(b);
      if (p.is_equal(2) && (is_a<GiNaC::symbol>(b) || (shared && !shared(b).empty())))
        return "(" + print(b) + "*" + print(b) + ")";
      return "pow(" + print(b) + ", " + print(p) + ")";
    }
    if (d_ == Dialect::Latex) return "{" + factor(b) + "}^{" + print(p) + "}";
    return factor(b) + "^" + factor(p);
  }
  std::string function(const ex& e) {
    ++operations;
    const auto& f = GiNaC::ex_to<GiNaC::function>(e);
    const unsigned s = f.get_serial();
    std::vector<std::string> a;
    for (size_t i = 0; i < e.nops(); ++i) a.push_back(print(e.op(i)));
    auto call = [&](const std::string& name) {
      std::string r = name + (d_ == Dialect::Latex ? "\\left(" : "(");
      for (size_t i = 0; i < a.size(); ++i) r += (i ? ", " : "") + a[i];
      return r + (d_ == Dialect::Latex ? "\\right)" : ")");
    };
    using namespace expr_detail;
    // The piecewise functions of the expression engine (expression.hpp), per dialect: the
    // expression language's own names, LaTeX operators, or the generated C file's static helpers.
    const int d = static_cast<int>(d_);  // C, Latex, Text
    static const char* const names[6][3] = {{"fabs", "", "abs"},
                                            {"rd_sgn", "\\operatorname{sgn}", ""},
                                            {"rd_min", "\\min", "min"},
                                            {"rd_max", "\\max", "max"},
                                            {"rd_step", "\\operatorname{step}", "step"},
                                            {"rd_clamp", "\\operatorname{clamp}", "clamp"}};
    const unsigned serials[6] = {serial_abs(), serial_sgn(), serial_min(), serial_max(), serial_step(), serial_clamp()};
    if (d_ == Dialect::Latex && s == serial_abs()) return "\\left|" + a[0] + "\\right|";
    if (d_ == Dialect::Text && s == serial_sgn()) return "if(" + a[0] + " >= 0, 1, -1)";
    for (int k = 0; k < 6; ++k)
      if (s == serials[k]) return call(names[k][d]);
    if (s == serial_if_lt() || s == serial_if_le()) {
      const bool lt = s == serial_if_lt();
      if (d_ == Dialect::Latex)
        return "\\begin{cases}" + a[2] + " & " + a[0] + (lt ? " < " : " \\le ") + a[1] + "\\\\ " + a[3] +
               " & \\text{otherwise}\\end{cases}";
      if (d_ == Dialect::Text) return "if(" + a[0] + (lt ? " < " : " <= ") + a[1] + ", " + a[2] + ", " + a[3] + ")";
      return "(" + a[0] + (lt ? " < " : " <= ") + a[1] + " ? " + a[2] + " : " + a[3] + ")";
    }
    if (d_ == Dialect::Text) return call(f.get_name());
    if (d_ == Dialect::Latex) {
      const std::string name = f.get_name();
      static const char* known[] = {"sin", "cos", "tan", "sinh", "cosh", "tanh", "exp", "log"};
      for (const char* k : known)
        if (name == k) return call(std::string("\\") + k);
      if (name == "asin" || name == "acos" || name == "atan") return call("\\arc" + name.substr(1));
      return call("\\operatorname{" + name + "}");
    }
    const std::string name = f.get_name();
    if (name == "atan2") return call("atan2");
    if (name == "abs") return call("fabs");
    return call(name);
  }

  Dialect d_;
  std::function<std::string(const GiNaC::symbol&)> leaf_;
};

// ----------------------------------------------------------------------------------------------
// C with common-subexpression elimination
// ----------------------------------------------------------------------------------------------
using ExCount = std::map<ex, int, GiNaC::ex_is_less>;

void count_uses(const ex& e, ExCount& count) {
  if (is_a<GiNaC::symbol>(e) || is_a<GiNaC::numeric>(e) || is_a<GiNaC::constant>(e)) return;
  if (count[e]++ > 0) return;
  for (size_t i = 0; i < e.nops(); ++i) count_uses(e.op(i), count);
}

/// One C block: `double tK = …;` temporaries, then `out[i] = …;` lines.
struct CBlock {
  std::string code;
  long temporaries = 0;
  long operations = 0;
};

CBlock c_block(const std::vector<std::pair<std::string, ex>>& outputs,
               const std::function<std::string(const GiNaC::symbol&)>& leaf, bool cse, const std::string& indent) {
  CBlock b;
  ExCount count;
  if (cse)
    for (const auto& [name, e] : outputs) count_uses(e, count);
  std::map<ex, std::string, GiNaC::ex_is_less> temp;
  Printer p(Dialect::C, leaf);
  std::function<std::string(const ex&)> shared_fn = [&](const ex& e) -> std::string {
    const auto it = temp.find(e);
    if (it != temp.end()) return it->second;
    const auto c = count.find(e);
    if (c == count.end() || c->second < 2) return "";
    // a shared node: print it once (its own children may be shared too)
    Printer inner(Dialect::C, leaf);
    inner.shared = shared_fn;
    const std::string text = inner.print_node(e);
    p.operations += inner.operations;
    const std::string name = "t" + std::to_string(b.temporaries++);
    b.code += indent + "const double " + name + " = " + text + ";\n";
    temp.emplace(e, name);
    return name;
  };
  if (cse) p.shared = shared_fn;
  for (const auto& [name, e] : outputs) {
    const std::string text = p.print(e);
    b.code += indent + name + " = " + text + ";\n";
  }
  b.operations = p.operations;
  return b;
}

std::string upper(std::string s) {
  for (char& ch : s) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  return s;
}

bool c_keyword(const std::string& s) {
  static const char* kw[] = {"auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else",
                             "enum", "extern", "float", "for", "goto", "if", "inline", "int", "long", "register",
                             "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch",
                             "typedef", "union", "unsigned", "void", "volatile", "while", "_Bool", "_Complex",
                             "_Imaginary"};
  for (const char* k : kw)
    if (s == k) return true;
  return false;
}

}  // namespace

// ----------------------------------------------------------------------------------------------
const std::string& SymbolicReferenceDynamics::prefix() const { return impl_->prefix; }
const SymbolicSummary& SymbolicReferenceDynamics::summary() const { return impl_->summary; }

namespace {

std::string param_field(const std::string& name) { return c_keyword(name) ? name + "_" : name; }

std::function<std::string(const GiNaC::symbol&)> c_leaf(const SymbolicReferenceDynamics::Impl& S) {
  std::map<std::string, std::string> names;
  names[S.t.get_name()] = "t";
  for (int i = 0; i < S.n; ++i) {
    names[S.q[i].get_name()] = "q[" + std::to_string(i) + "]";
    names[S.qd[i].get_name()] = "qd[" + std::to_string(i) + "]";
  }
  for (int k = 0; k < S.nz; ++k) names[S.z[k].get_name()] = "z[" + std::to_string(k) + "]";
  for (size_t k = 0; k < S.params.size(); ++k) names[S.params[k].get_name()] = "p->" + param_field(S.param_names[k]);
  return [names](const GiNaC::symbol& s) {
    const auto it = names.find(s.get_name());
    if (it == names.end()) throw Error("generate: unbound symbol " + s.get_name());
    return it->second;
  };
}

}  // namespace

std::string SymbolicReferenceDynamics::c_header() const {
  const Impl& S = *impl_;
  const std::string P = S.prefix, U = upper(S.prefix);
  std::ostringstream o;
  o << "/* Reference dynamics of '" << S.name << "', generated by refdyn (refdyn generate).\n"
    << " * C99, depends only on libm. State x = [q (" << S.n << "), qd (" << S.n << "), z (" << S.nz << ")].\n"
    << " * Coordinates:";
  for (int i = 0; i < S.n; ++i) o << " q[" << i << "] = " << S.joints[i] << (i + 1 < S.n ? "," : ".\n");
  if (S.n == 0) o << "\n";
  if (S.nz) {
    o << " * Force-element states:";
    for (int k = 0; k < S.nz; ++k) o << " z[" << k << "] = " << S.states[k] << (k + 1 < S.nz ? "," : ".\n");
  }
  o << " * Matrices are row-major. */\n"
    << "#ifndef " << U << "H\n#define " << U << "H\n\n"
    << "#define " << U << "NQ " << S.n << "\n#define " << U << "NZ " << S.nz << "\n#define " << U << "NX "
    << 2 * S.n + S.nz << "\n#define " << U << "NC " << S.m << "\n\n"
    << "#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n"
    << "/* Parameters: the scenario's named constants the formulas use, and the Baumgarte gains. */\n"
    << "typedef struct {\n";
  for (size_t k = 0; k < S.param_names.size(); ++k)
    o << "  double " << param_field(S.param_names[k]) << ";  /* default " << double_text(S.param_values[k], 17) << " */\n";
  o << "  double rd_alpha;  /* Baumgarte alpha [1/s], default " << double_text(S.alpha, 17) << " */\n"
    << "  double rd_beta;   /* Baumgarte beta [1/s], default " << double_text(S.beta, 17) << " */\n"
    << "  double rd_beta1;  /* first-order rows: beta_1 [1/s], default " << double_text(S.beta1, 17) << " */\n"
    << "} " << P << "params;\n\n"
    << "/* The scenario's values. */\nvoid " << P << "default_params(" << P << "params* p);\n"
    << "/* M(q), NQ x NQ. */\nvoid " << P << "mass(const double* x, const " << P << "params* p, double* M);\n"
    << "/* c(q, qd) (velocity products) and g(q) (gravity), NQ each: M qdd + c + g = Q + constraint forces. */\n"
    << "void " << P << "bias(const double* x, const " << P << "params* p, double* c, double* g);\n"
    << "/* Q(t, q, qd, z) of the force elements (NQ) and the rates of their states (NZ). */\n"
    << "void " << P << "forces(double t, const double* x, const " << P << "params* p, double* Q, double* zdot);\n"
    << "/* Constraint rows (NC): phi (holonomic: Phi; first order: c), phid (Phi dot; c), A (NC x NQ), gamma:\n"
    << " * d2Phi/dt2 = A qdd + gamma (holonomic), dc/dt = A qdd + gamma (first order), A qdd + gamma = 0\n"
    << " * (acceleration rows, whose phi and phid are 0). */\n"
    << "void " << P << "constraints(double t, const double* x, const " << P
    << "params* p, double* phi, double* phid, double* A, double* gamma);\n"
    << "/* xdot = f(t, x) of the reference dynamics (projection, null-space method). Returns 0, or 1 if the\n"
    << " * partition's K_dc or N^T M N is singular (xdot is then not written). */\n"
    << "int " << P << "rhs(double t, const double* x, const " << P << "params* p, double* xdot);\n\n"
    << "#ifdef __cplusplus\n}\n#endif\n#endif\n";
  return o.str();
}

std::string SymbolicReferenceDynamics::c_source() const {
  const Impl& S = *impl_;
  const std::string P = S.prefix;
  const int n = S.n, m = S.m;
  const auto leaf = c_leaf(S);
  const bool cse = S.cse;
  std::ostringstream o;
  long temporaries = 0, operations = 0;
  auto block = [&](const std::vector<std::pair<std::string, ex>>& outs) {
    CBlock b = c_block(outs, leaf, cse, "  ");
    temporaries += b.temporaries;
    operations += b.operations;
    return b.code;
  };
  const std::string unpack = "  const double* q = x;\n  const double* qd = x + " + std::to_string(n) +
                             ";\n  const double* z = x + " + std::to_string(2 * n) +
                             ";\n  (void)q;\n  (void)qd;\n  (void)z;\n  (void)p;\n";
  o << "/* Reference dynamics of '" << S.name << "', generated by refdyn. See reference_dynamics.h. */\n"
    << "#include \"reference_dynamics.h\"\n\n#include <math.h>\n\n";
  const std::size_t helpers_at = static_cast<std::size_t>(o.tellp());
  o << "void " << P << "default_params(" << P << "params* p) {\n";
  for (size_t k = 0; k < S.param_names.size(); ++k)
    o << "  p->" << param_field(S.param_names[k]) << " = " << double_text(S.param_values[k], 17) << ";\n";
  o << "  p->rd_alpha = " << double_text(S.alpha, 17) << ";\n  p->rd_beta = " << double_text(S.beta, 17)
    << ";\n  p->rd_beta1 = " << double_text(S.beta1, 17) << ";\n}\n\n";
  {
    std::vector<std::pair<std::string, ex>> outs;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) outs.emplace_back("M[" + std::to_string(i * n + j) + "]", S.M[i * n + j]);
    o << "void " << P << "mass(const double* x, const " << P << "params* p, double* M) {\n" << unpack << block(outs) << "}\n\n";
  }
  {
    std::vector<std::pair<std::string, ex>> outs;
    for (int i = 0; i < n; ++i) outs.emplace_back("c[" + std::to_string(i) + "]", S.c[i]);
    for (int i = 0; i < n; ++i) outs.emplace_back("g[" + std::to_string(i) + "]", S.g[i]);
    o << "void " << P << "bias(const double* x, const " << P << "params* p, double* c, double* g) {\n" << unpack
      << block(outs) << "}\n\n";
  }
  {
    std::vector<std::pair<std::string, ex>> outs;
    for (int i = 0; i < n; ++i) outs.emplace_back("Q[" + std::to_string(i) + "]", S.Q[i]);
    for (int k = 0; k < S.nz; ++k) outs.emplace_back("zdot[" + std::to_string(k) + "]", S.zdot[k]);
    o << "void " << P << "forces(double t, const double* x, const " << P << "params* p, double* Q, double* zdot) {\n"
      << unpack << "  (void)t;\n  (void)Q;\n  (void)zdot;\n" << block(outs) << "}\n\n";
  }
  {
    std::vector<std::pair<std::string, ex>> outs;
    for (int r = 0; r < m; ++r) {
      outs.emplace_back("phi[" + std::to_string(r) + "]", S.phi[r]);
      outs.emplace_back("phid[" + std::to_string(r) + "]", S.phid[r]);
      for (int i = 0; i < n; ++i) outs.emplace_back("A[" + std::to_string(r * n + i) + "]", S.A[r * n + i]);
      outs.emplace_back("gamma[" + std::to_string(r) + "]", S.gamma[r]);
    }
    o << "void " << P << "constraints(double t, const double* x, const " << P
      << "params* p, double* phi, double* phid, double* A, double* gamma) {\n"
      << unpack << "  (void)t;\n  (void)phi;\n  (void)phid;\n  (void)A;\n  (void)gamma;\n" << block(outs) << "}\n\n";
  }
  // The solve: q̈ = q̈_p + N u, K_dc q̈_p,dep = rhs (q̈_p,ind = 0), (NᵀMN) u = Nᵀ(F − M q̈_p),
  // N = [I; −K_dc⁻¹ K_ic] in (independent; dependent) order. Small dense LU with partial pivoting.
  const int k = n - m;
  auto list = [](const std::vector<int>& v) {
    std::string s;
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    return s.empty() ? std::string("0") : s;
  };
  o << "/* Solves A X = B in place (A: r x r, B: r x c, row-major) by LU with partial pivoting; 1 if singular. */\n"
    << "static int rd_solve(int r, int c, double* A, double* B) {\n"
    << "  for (int j = 0; j < r; ++j) {\n"
    << "    int piv = j;\n"
    << "    for (int i = j + 1; i < r; ++i) if (fabs(A[i * r + j]) > fabs(A[piv * r + j])) piv = i;\n"
    << "    if (!(fabs(A[piv * r + j]) > 0.0)) return 1;\n"
    << "    if (piv != j) {\n"
    << "      for (int l = 0; l < r; ++l) { double s = A[j * r + l]; A[j * r + l] = A[piv * r + l]; A[piv * r + l] = s; }\n"
    << "      for (int l = 0; l < c; ++l) { double s = B[j * c + l]; B[j * c + l] = B[piv * c + l]; B[piv * c + l] = s; }\n"
    << "    }\n"
    << "    for (int i = j + 1; i < r; ++i) {\n"
    << "      const double f = A[i * r + j] / A[j * r + j];\n"
    << "      for (int l = j; l < r; ++l) A[i * r + l] -= f * A[j * r + l];\n"
    << "      for (int l = 0; l < c; ++l) B[i * c + l] -= f * B[j * c + l];\n"
    << "    }\n"
    << "  }\n"
    << "  for (int j = r - 1; j >= 0; --j)\n"
    << "    for (int l = 0; l < c; ++l) {\n"
    << "      double s = B[j * c + l];\n"
    << "      for (int i = j + 1; i < r; ++i) s -= A[j * r + i] * B[i * c + l];\n"
    << "      B[j * c + l] = s / A[j * r + j];\n"
    << "    }\n"
    << "  return 0;\n}\n\n";
  const std::string N = std::to_string(n), Mr = std::to_string(std::max(m, 1)), K = std::to_string(std::max(k, 1));
  o << "int " << P << "rhs(double t, const double* x, const " << P << "params* p, double* xdot) {\n"
    << "  enum { n = " << n << ", m = " << m << ", k = " << k << ", nz = " << S.nz << " };\n"
    << "  static const int ind[" << K << "] = {" << list(S.independent) << "};\n"
    << "  static const int dep[" << Mr << "] = {" << list(S.dependent) << "};\n"
    << "  static const int order[" << Mr << "] = {";
  {
    std::string s;
    for (int r = 0; r < m; ++r) s += (r ? ", " : "") + std::to_string(static_cast<int>(S.row_order[r]));
    o << (s.empty() ? "0" : s);
  }
  o << "};  /* per row: 0 position, 1 velocity, 2 acceleration */\n"
    << "  double M[" << n * n << "], c[" << N << "], g[" << N << "], Q[" << N << "], zdot[" << std::max(S.nz, 1)
    << "], F[" << N << "];\n"
    << "  double phi[" << Mr << "], phid[" << Mr << "], A[" << std::max(m, 1) * n << "], gamma[" << Mr << "];\n"
    << "  double Kdc[" << std::max(m, 1) * std::max(m, 1) << "], G[" << std::max(m, 1) * std::max(k, 1) << "], rhs["
    << Mr << "];\n"
    << "  double Nm[" << n * std::max(k, 1) << "], qddp[" << N << "], NMN[" << std::max(k, 1) * std::max(k, 1)
    << "], u[" << K << "], MN[" << n * std::max(k, 1) << "], r[" << N << "];\n"
    << "  (void)ind; (void)dep; (void)order; (void)Kdc; (void)G; (void)rhs; (void)phi; (void)phid; (void)A;\n"
    << "  (void)gamma;\n"
    << "  " << P << "mass(x, p, M);\n  " << P << "bias(x, p, c, g);\n  " << P << "forces(t, x, p, Q, zdot);\n"
    << "  for (int i = 0; i < n; ++i) F[i] = Q[i] - c[i] - g[i];\n";
  if (m > 0) {
    o << "  " << P << "constraints(t, x, p, phi, phid, A, gamma);\n"
      << "  for (int i = 0; i < m; ++i)\n"
      << "    rhs[i] = order[i] == 2   ? -gamma[i]\n"
      << "             : order[i] == 1 ? -gamma[i] - p->rd_beta1 * phi[i]\n"
      << "                             : -gamma[i] - 2.0 * p->rd_alpha * phid[i] - p->rd_beta * p->rd_beta * phi[i];\n"
      << "  /* G = K_dc^-1 [K_ic, rhs] */\n"
      << "  double KR[" << std::max(m, 1) * (std::max(k, 0) + 1) << "];\n"
      << "  for (int i = 0; i < m; ++i) {\n"
      << "    for (int j = 0; j < m; ++j) Kdc[i * m + j] = A[i * n + dep[j]];\n"
      << "    for (int j = 0; j < k; ++j) KR[i * (k + 1) + j] = A[i * n + ind[j]];\n"
      << "    KR[i * (k + 1) + k] = rhs[i];\n"
      << "  }\n"
      << "  if (rd_solve(m, k + 1, Kdc, KR)) return 1;\n"
      << "  for (int i = 0; i < n * k; ++i) Nm[i] = 0.0;\n"
      << "  for (int i = 0; i < n; ++i) qddp[i] = 0.0;\n"
      << "  for (int j = 0; j < k; ++j) Nm[ind[j] * k + j] = 1.0;\n"
      << "  for (int i = 0; i < m; ++i) {\n"
      << "    for (int j = 0; j < k; ++j) Nm[dep[i] * k + j] = -KR[i * (k + 1) + j];\n"
      << "    qddp[dep[i]] = KR[i * (k + 1) + k];\n"
      << "  }\n";
  } else {
    o << "  for (int i = 0; i < n * k; ++i) Nm[i] = 0.0;\n"
      << "  for (int j = 0; j < k; ++j) Nm[ind[j] * k + j] = 1.0;\n"
      << "  for (int i = 0; i < n; ++i) qddp[i] = 0.0;\n";
  }
  o << "  /* (N^T M N) u = N^T (F - M qddp) */\n"
    << "  for (int i = 0; i < n; ++i) {\n"
    << "    double s = F[i];\n"
    << "    for (int j = 0; j < n; ++j) s -= M[i * n + j] * qddp[j];\n"
    << "    r[i] = s;\n"
    << "    for (int j = 0; j < k; ++j) {\n"
    << "      double v = 0.0;\n"
    << "      for (int l = 0; l < n; ++l) v += M[i * n + l] * Nm[l * k + j];\n"
    << "      MN[i * k + j] = v;\n"
    << "    }\n"
    << "  }\n"
    << "  for (int a = 0; a < k; ++a) {\n"
    << "    double s = 0.0;\n"
    << "    for (int l = 0; l < n; ++l) s += Nm[l * k + a] * r[l];\n"
    << "    u[a] = s;\n"
    << "    for (int b = 0; b < k; ++b) {\n"
    << "      double v = 0.0;\n"
    << "      for (int l = 0; l < n; ++l) v += Nm[l * k + a] * MN[l * k + b];\n"
    << "      NMN[a * k + b] = v;\n"
    << "    }\n"
    << "  }\n"
    << "  if (k > 0 && rd_solve(k, 1, NMN, u)) return 1;\n"
    << "  for (int i = 0; i < n; ++i) {\n"
    << "    double s = qddp[i];\n"
    << "    for (int j = 0; j < k; ++j) s += Nm[i * k + j] * u[j];\n"
    << "    xdot[i] = x[n + i];\n"
    << "    xdot[n + i] = s;\n"
    << "  }\n"
    << "  for (int i = 0; i < nz; ++i) xdot[2 * n + i] = zdot[i];\n"
    << "  return 0;\n}\n";
  // The piecewise helpers the formulas use (only those: no unused static functions).
  std::string text = o.str();
  std::string helpers;
  const std::pair<const char*, const char*> defs[] = {
      {"rd_sgn(", "static double rd_sgn(double u) { return u >= 0 ? 1.0 : -1.0; }\n"},
      {"rd_min(", "static double rd_min(double a, double b) { return a <= b ? a : b; }\n"},
      {"rd_max(", "static double rd_max(double a, double b) { return a >= b ? a : b; }\n"},
      {"rd_step(", "static double rd_step(double u) { return u >= 0 ? 1.0 : 0.0; }\n"},
      {"rd_clamp(", "static double rd_clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }\n"}};
  for (const auto& [use, def] : defs)
    if (text.find(use, helpers_at) != std::string::npos) helpers += def;
  if (!helpers.empty()) text.insert(helpers_at, helpers + "\n");
  impl_->summary.c_temporaries = temporaries;
  impl_->summary.c_operations = operations;
  return text;
}


// ----------------------------------------------------------------------------------------------
// LaTeX
// ----------------------------------------------------------------------------------------------
namespace {


class LatexWriter {
 public:
  /// `shown`: every expression the document displays (for counting shared sub-expressions).
  LatexWriter(const SymbolicReferenceDynamics::Impl& S, const std::vector<ex>& shown)
      : p_(Dialect::Latex, [](const GiNaC::symbol& s) { return s.get_TeX_name(); }) {
    for (int i = 0; i < S.n; ++i) qindex_[S.q[i].get_name()] = i + 1;
    for (const ex& e : shown) count_uses(e, count_);
    p_.memo = &memo_;
    p_.shared = [this](const ex& e) { return shared(e); };
  }
  /// "lhs &= rhs \\" with a line break every ~140 characters of a long top-level sum.
  std::string equation(const std::string& lhs, const ex& e) {
    std::string body;
    if (is_a<GiNaC::add>(e) && e.nops() > 3) {
      std::size_t width = 0;
      for (size_t i = 0; i < e.nops(); ++i) {
        const ex t = e.op(i);
        const bool neg = Printer::negative_term(t);
        const std::string term = p_.print(neg ? ex(-t) : t);
        if (i > 0 && width + term.size() > 140) {
          body += " \\\\\n  &\\quad";
          width = 0;
        }
        body += (i == 0 ? (neg ? "-" : "") : (neg ? " - " : " + ")) + term;
        width += term.size() + 3;
      }
    } else {
      const std::string abbreviation = trig(e);
      body = !abbreviation.empty() ? abbreviation
             : (is_a<GiNaC::symbol>(e) || is_a<GiNaC::numeric>(e)) ? p_.print(e)
                                                                  : p_.print_node(e);
    }
    return "  " + lhs + " &= " + body + " \\\\\n";
  }
  /// The auxiliary quantities u_k the printed equations use, defined in order.
  std::string definitions() {
    std::string out;
    for (std::size_t k = 0; k < defs_.size(); ++k) out += equation("u_{" + std::to_string(k + 1) + "}", defs_[k]);
    return out;
  }
  std::size_t size() const { return defs_.size(); }

 private:
  /// sin(q_i), cos(q_i) → s_i, c_i
  std::string trig(const ex& e) const {
    if (!is_a<GiNaC::function>(e) || e.nops() != 1 || !is_a<GiNaC::symbol>(e.op(0))) return "";
    const auto it = qindex_.find(GiNaC::ex_to<GiNaC::symbol>(e.op(0)).get_name());
    if (it == qindex_.end()) return "";
    const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
    if (name == "sin") return "s_{" + std::to_string(it->second) + "}";
    if (name == "cos") return "c_{" + std::to_string(it->second) + "}";
    return "";
  }
  /// A sub-expression becomes an auxiliary u_k when it is shared and not short, or long.
  std::string shared(const ex& e) {
    const std::string abbreviation = trig(e);
    if (!abbreviation.empty()) return abbreviation;
    if (is_a<GiNaC::symbol>(e) || is_a<GiNaC::numeric>(e) || is_a<GiNaC::constant>(e)) return "";
    const auto t = temp_.find(e);
    if (t != temp_.end()) return t->second;
    if (memo_.count(e)) return "";  // decided: printed inline
    const std::string text = p_.print_node(e);
    const auto c = count_.find(e);
    const int uses = c == count_.end() ? 1 : c->second;
    if ((uses >= 2 && text.size() >= 40) || text.size() >= 300) {
      defs_.push_back(e);
      const std::string name = "u_{" + std::to_string(defs_.size()) + "}";
      temp_.emplace(e, name);
      return name;
    }
    memo_.emplace(e, text);
    return "";
  }

  Printer p_;
  std::map<std::string, int> qindex_;
  ExCount count_;
  std::map<ex, std::string, GiNaC::ex_is_less> memo_, temp_;
  std::vector<ex> defs_;
};

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

}  // namespace

std::string SymbolicReferenceDynamics::latex() const {
  const Impl& S = *impl_;
  const int n = S.n, m = S.m;
  std::vector<ex> shown;
  for (const auto* v : {&S.M, &S.c, &S.g, &S.Q, &S.zdot, &S.phi, &S.phid, &S.A, &S.gamma})
    shown.insert(shown.end(), v->begin(), v->end());
  LatexWriter w(S, shown);
  std::ostringstream o;
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
      for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::string("q_{") + std::to_string(v[i] + 1) + "}";
      return s;
    };
    o << "\\begin{align*}\n  N^{\\mathsf T}\\bigl(M\\ddot q + c + g - Q\\bigr) &= 0, \\qquad "
      << "N = \\frac{\\partial \\dot q}{\\partial \\dot q_{ic}} = \\begin{pmatrix} I \\\\ -K_{dc}^{-1}K_{ic}\\end{pmatrix},\n"
      << "\\end{align*}\n"
      << "in the independent coordinates $q_{ic} = (" << idx(S.independent) << ")$ with the dependent ones $q_{dc} = ("
      << idx(S.dependent) << ")$; $K_{ic}$ and $K_{dc}$ are the columns of $A$ of $q_{ic}$ and $q_{dc}$ "
      << "(rows of $N$ in the order $q_{ic}, q_{dc}$).\n\n";
  } else {
    o << "$M\\ddot q + c + g = Q$ (no constraints).\n\n";
  }
  const std::size_t equations_at = static_cast<std::size_t>(o.tellp());
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
  if (m > 0) {
    o << "\\section*{Constraints}\n";
    for (int r = 0; r < m; ++r) {
      const std::string R = std::to_string(r + 1);
      o << "\\paragraph{Row " << R << ": \\texttt{" << latex_text(S.row_names[r]) << "}} (" << S.row_origin[r] << ", "
        << (S.row_order[r] == 2 ? "acceleration level: $A\\ddot q + \\gamma = 0$, imposed exactly"
                                : S.row_order[r] == 1 ? "velocity level" : "position level")
        << ")\n\\begin{align*}\n";
      if (S.row_order[r] < 2) o << w.equation(S.row_order[r] ? "c_{" + R + "}" : "\\Phi_{" + R + "}", S.phi[r]);
      if (S.row_order[r] == 0) o << w.equation("\\dot\\Phi_{" + R + "}", S.phid[r]);
      for (int i = 0; i < n; ++i)
        if (!S.A[r * n + i].is_zero()) o << w.equation("A_{" + R + "," + std::to_string(i + 1) + "}", S.A[r * n + i]);
      o << w.equation("\\gamma_{" + R + "}", S.gamma[r]) << "\\end{align*}\n";
    }
  }
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
  Printer p(Dialect::Text, [](const GiNaC::symbol& s) { return s.get_name(); });
  auto str = [&](const ex& e) { return json_quote(p.print(e)); };
  auto ints = [](const std::vector<int>& v) {
    std::string s = "[";
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    return s + "]";
  };
  std::ostringstream o;
  o << "{\n  \"generator\": \"refdyn generate\",\n  \"name\": " << json_quote(S.name) << ",\n"
    << "  \"syntax\": \"refdyn expression language: q(j), qd(j) joint coordinates and velocities, state(k) force-element "
       "states, t time, named parameters\",\n"
    << "  \"joints\": [";
  for (int i = 0; i < n; ++i) o << (i ? ", " : "") << json_quote(S.joints[i]);
  o << "],\n  \"states\": [";
  for (int k = 0; k < S.nz; ++k) o << (k ? ", " : "") << json_quote(S.states[k]);
  o << "],\n  \"parameters\": {";
  for (size_t k = 0; k < S.param_names.size(); ++k)
    o << (k ? ", " : "") << json_quote(S.param_names[k]) << ": " << double_text(S.param_values[k], 17);
  o << "},\n  \"baumgarte\": {\"alpha\": " << double_text(S.alpha, 17) << ", \"beta\": " << double_text(S.beta, 17)
    << ", \"beta_first_order\": " << double_text(S.beta1, 17) << "},\n"
    << "  \"independent\": " << ints(S.independent) << ",\n  \"dependent\": " << ints(S.dependent) << ",\n"
    << "  \"M\": [";
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
      << ", \"order\": " << (S.row_order[r] == 2 ? "\"acceleration\"" : S.row_order[r] ? "\"velocity\"" : "\"position\"")
      << ",\n     \"phi\": " << str(S.phi[r])
      << ",\n     \"phid\": " << str(S.phid[r]) << ",\n     \"A\": [";
    for (int i = 0; i < n; ++i) o << (i ? ", " : "") << str(S.A[r * n + i]);
    o << "],\n     \"gamma\": " << str(S.gamma[r]) << "}";
  }
  o << (m ? "\n  " : "") << "]\n}\n";
  return o.str();
}

}  // namespace refdyn
