// Expression engine, stage 2: lowering to GiNaC. Builds the GiNaC expression from the front
// end's text (parameters substituted as exact constants), differentiates it exactly, and
// locates constant sub-expressions that are not finite real numbers.
#include "internal.hpp"

#include "refdyn/error.hpp"
#include "refdyn/text.hpp"

#include <sstream>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

bool has_symbol(const ex& e) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) return true;
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_symbol(e.op(i))) return true;
  return false;
}

std::string to_text(const ex& e) {
  std::ostringstream os;
  os << e;
  return os.str();
}

/// Thrown by the compiler for a constant that is not a finite real number; the constructor
double constant_value(const ex& e) {
  ex v;
  try {
    v = e.evalf();
  } catch (const std::exception& err) {
    throw BadConstant{std::string("cannot be evaluated (") + err.what() + ")", to_text(e), true};
  }
  if (!GiNaC::is_a<GiNaC::numeric>(v))
    throw BadConstant{"does not evaluate to a number (got " + to_text(v) + ")", to_text(e), false};
  const GiNaC::numeric& num = GiNaC::ex_to<GiNaC::numeric>(v);
  if (!num.is_real())
    throw BadConstant{"is not a real number (got " + to_text(v) + ")", to_text(e), false};
  double d = num.to_double();
  if (!std::isfinite(d))
    throw BadConstant{"evaluates to " + fmt(d), to_text(e), true};
  return d;
}

namespace {

/// The innermost located source sub-expression for which `bad` holds (nullptr if none).
template <class Bad>
const Node* locate(const ParseResult& fe, Bad&& bad) {
  for (const Node& node : fe.nodes) {
    try {
      GiNaC::parser p(fe.symtab, true);
      if (bad(p(node.ginac_text))) return &node;
    } catch (...) {
      return &node;
    }
  }
  return nullptr;
}

[[noreturn]] void fail_node(const std::string& text, const Node* node, const std::string& what,
                            const std::string& hint) {
  if (node)
    fail_at(text, node->pos, node->end - node->pos,
            what + " in '" + text.substr(node->pos, node->end - node->pos) + "'", hint);
  fail_at(text, std::string::npos, 0, what, hint);
}

std::string parameter_hint(const ParseResult& fe) {
  if (fe.used_parameters.empty()) return "check the constants in the expression";
  std::string s = "check the parameter values (";
  bool first = true;
  for (const auto& [name, v] : fe.used_parameters) {
    s += (first ? "" : ", ") + name + " = " + fmt(v);
    first = false;
  }
  return s + ")";
}

}  // namespace

Symbolic lower_symbolic(const std::string& text, const ParseResult& fe,
                        const std::vector<GiNaC::realsymbol>& syms, const ExpressionOptions& opt) {
  const int derivative_order = opt.derivative_order;
  const int n = static_cast<int>(syms.size());
  const std::string param_hint = parameter_hint(fe);
  Symbolic s;
  ex& value = s.value;
  try {
    GiNaC::parser p(fe.symtab, true);
    value = p(fe.ginac_text);
  } catch (const GiNaC::parse_error& err) {
    fail_at(text, std::string::npos, 0,
            std::string("GiNaC could not parse the expression (") + err.what() + ")",
            "please report this: the front end accepted the syntax");
  } catch (const std::exception& err) {
    std::string msg = err.what();
    const Node* node = locate(fe, [](const ex&) { return false; });
    if (msg.find("division by zero") != std::string::npos)
      fail_node(text, node, "division by zero: a constant sub-expression is infinite", param_hint);
    fail_node(text, node, "a constant sub-expression cannot be evaluated (" + msg + ")",
              param_hint);
  }

  // Derivatives.
  std::vector<ex>& grad = s.grad;
  std::vector<ex>& hess = s.hess;
  grad.assign(n, ex(0));
  hess.assign(static_cast<std::size_t>(n) * n, ex(0));
  for (int i = 0; i < n; ++i)
    if (value.has(syms[i])) s.used.push_back(i);
  try {
    if (derivative_order >= 1)
      for (int i : s.used) grad[i] = value.diff(syms[i]);
    if (derivative_order >= 2)
      for (int i : s.used)
        for (int j : s.used)
          if (j >= i) hess[i * n + j] = hess[j * n + i] = grad[i].diff(syms[j]);
  } catch (const std::exception& err) {
    fail_at(text, std::string::npos, 0,
            std::string("differentiation failed (") + err.what() + ")", param_hint);
  }

  // Hessian entries for detecting a constant Hessian when it was not requested.
  const bool try_quadratic = opt.specialize && derivative_order >= 1 &&
                             static_cast<int>(s.used.size()) <= kMaxQuadratic;
  s.hessian_constant = try_quadratic;
  if (try_quadratic) {
    try {
      for (int i : s.used)
        for (int j : s.used) {
          if (j < i) continue;
          ex h = derivative_order >= 2 ? hess[i * n + j] : grad[i].diff(syms[j]);
          if (has_symbol(h)) s.hessian_constant = false;
          if (derivative_order < 2) hess[i * n + j] = hess[j * n + i] = h;
        }
    } catch (const std::exception&) {
      s.hessian_constant = false;
    }
  }
  return s;
}

void fail_bad_constant(const std::string& text, const ParseResult& fe, const BadConstant& bc) {
  auto is_bad = [](const ex& e) {
    if (has_symbol(e)) return false;
    try {
      constant_value(e);
      return false;
    } catch (const BadConstant&) {
      return true;
    }
  };
  const Node* node = locate(fe, is_bad);
  std::string what = bc.infinite ? "a constant sub-expression is infinite ('" + bc.constant +
                                       "' " + bc.what + ")"
                                 : "non-numeric leftover: a constant sub-expression " + bc.what;
  fail_node(text, node, what, parameter_hint(fe));
}

}  // namespace expr_detail
}  // namespace refdyn
