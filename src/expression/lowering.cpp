// Expression engine, stage 2: lowering to GiNaC. Builds the GiNaC expression from the front
// end's syntax tree (parameters substituted as exact constants) in one forward pass,
// differentiates it exactly, and locates constant sub-expressions that are not finite real
// numbers. Also defines the piecewise GiNaC functions (abs, min, max, step, clamp, if) with
// exact one-sided derivatives.
#include "internal.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cln/float.h>
#include <stdexcept>

#include <sstream>
#include <unordered_set>

namespace refdyn {
namespace expr_detail {

using GiNaC::ex;

namespace {
/// True if `pred` holds for some node of e: an iterative walk that visits each shared object
/// once (derivatives are DAGs whose tree expansion can be far larger than their size).
template <class Pred>
bool any_node(const ex& root, Pred&& pred) {
  std::vector<ex> stack{root}, seen_alive;
  std::unordered_set<const GiNaC::basic*> seen;
  while (!stack.empty()) {
    ex e = std::move(stack.back());
    stack.pop_back();
    if (!seen.insert(&GiNaC::ex_to<GiNaC::basic>(e)).second) continue;
    if (pred(e)) return true;
    for (std::size_t i = 0; i < e.nops(); ++i) stack.push_back(e.op(i));
    seen_alive.push_back(std::move(e));  // keeps the address valid while it is a key
  }
  return false;
}
}  // namespace

bool has_symbol(const ex& e) {
  return any_node(e, [](const ex& x) { return GiNaC::is_a<GiNaC::symbol>(x); });
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

// ------------------------------------------------------------------------------------------
// Piecewise functions. Values select a branch; derivatives are taken inside the branch that
// the same selection picks (so gradient and Hessian agree with the value's branch at a tie),
// never through the selection: d/dx if(c, a, b) = if(c, da/dx, db/dx). All exact, all finite
// wherever the branches' derivatives are.
// ------------------------------------------------------------------------------------------
namespace {

bool real_number(const ex& e) {
  return GiNaC::is_a<GiNaC::numeric>(e) && GiNaC::ex_to<GiNaC::numeric>(e).is_real();
}
const GiNaC::numeric& num(const ex& e) { return GiNaC::ex_to<GiNaC::numeric>(e); }

unsigned abs_serial, sgn_serial, if_lt_serial, if_le_serial, min_serial, max_serial, step_serial,
    clamp_serial;

GiNaC::function make_abs(const ex& u) { return GiNaC::function(abs_serial, u); }
GiNaC::function make_sgn(const ex& u) { return GiNaC::function(sgn_serial, u); }
GiNaC::function make_if(bool strict, const ex& x, const ex& y, const ex& a, const ex& b) {
  return GiNaC::function(strict ? if_lt_serial : if_le_serial, x, y, a, b);
}

// min, max, step and clamp are functions of their own rather than if() forms so that each
// argument occurs once in the tree: nested min(min(min(...))) stays linear in size (an if()
// form repeats the arguments in the condition, which doubles the tree per level for every
// GiNaC operation that walks trees: diff, printing, has()).
GiNaC::function make_min(const ex& a, const ex& b) { return GiNaC::function(min_serial, a, b); }
GiNaC::function make_max(const ex& a, const ex& b) { return GiNaC::function(max_serial, a, b); }
GiNaC::function make_step(const ex& u) { return GiNaC::function(step_serial, u); }
GiNaC::function make_clamp(const ex& x, const ex& lo, const ex& hi) {
  return GiNaC::function(clamp_serial, x, lo, hi);
}

// min: a where a <= b (ties: a); max: a where a >= b (ties: a).
template <bool Max>
ex minmax_eval(const ex& a, const ex& b) {
  if (a.is_equal(b)) return a;
  if (real_number(a) && real_number(b)) return (Max ? num(b) <= num(a) : num(a) <= num(b)) ? a : b;
  return (Max ? make_max(a, b) : make_min(a, b)).hold();
}
template <bool Max>
ex minmax_deriv(const ex& a, const ex& b, const GiNaC::symbol& s) {
  return Max ? make_if(false, b, a, a.diff(s), b.diff(s))
             : make_if(false, a, b, a.diff(s), b.diff(s));
}
// step(u) = u >= 0 ? 1 : 0.
ex step_eval(const ex& u) {
  if (real_number(u)) return num(u).is_negative() ? ex(0) : ex(1);
  return make_step(u).hold();
}
ex step_deriv(const ex&, const GiNaC::symbol&) { return 0; }
// clamp(x, lo, hi) = x < lo ? lo : (hi < x ? hi : x).
ex clamp_eval(const ex& x, const ex& lo, const ex& hi) {
  if (real_number(x) && real_number(lo) && real_number(hi))
    return num(x) < num(lo) ? lo : (num(hi) < num(x) ? hi : x);
  return make_clamp(x, lo, hi).hold();
}
ex clamp_deriv(const ex& x, const ex& lo, const ex& hi, const GiNaC::symbol& s) {
  return make_if(true, x, lo, lo.diff(s), make_if(true, hi, x, hi.diff(s), x.diff(s)));
}

ex abs_eval(const ex& u) {
  if (real_number(u)) return GiNaC::abs(num(u));
  return make_abs(u).hold();
}
ex abs_evalf(const ex& u) {
  if (real_number(u)) return GiNaC::abs(num(u));
  return make_abs(u).hold();
}
ex abs_deriv(const ex& u, const GiNaC::symbol& s) { return make_sgn(u) * u.diff(s); }

ex sgn_eval(const ex& u) {
  if (real_number(u)) return num(u).is_negative() ? ex(-1) : ex(1);
  return make_sgn(u).hold();
}
ex sgn_deriv(const ex&, const GiNaC::symbol&) { return 0; }

template <bool Strict>
ex if_eval(const ex& x, const ex& y, const ex& a, const ex& b) {
  if (a.is_equal(b)) return a;
  if (real_number(x) && real_number(y)) {
    const bool take_a = Strict ? num(x) < num(y) : num(x) <= num(y);
    return take_a ? a : b;
  }
  return make_if(Strict, x, y, a, b).hold();
}
template <bool Strict>
ex if_evalf(const ex& x, const ex& y, const ex& a, const ex& b) {
  if (real_number(x) && real_number(y)) {
    const bool take_a = Strict ? num(x) < num(y) : num(x) <= num(y);
    return take_a ? a : b;
  }
  return make_if(Strict, x, y, a, b).hold();
}
template <bool Strict>
ex if_deriv(const ex& x, const ex& y, const ex& a, const ex& b, const GiNaC::symbol& s) {
  return make_if(Strict, x, y, a.diff(s), b.diff(s));
}

struct Registration {
  Registration() {
    using GiNaC::function_options;
    abs_serial = GiNaC::function::register_new(function_options("rd_abs", 1)
                                                   .eval_func(abs_eval)
                                                   .evalf_func(abs_evalf)
                                                   .expl_derivative_func(abs_deriv));
    sgn_serial = GiNaC::function::register_new(function_options("rd_sgn", 1)
                                                   .eval_func(sgn_eval)
                                                   .evalf_func(sgn_eval)
                                                   .expl_derivative_func(sgn_deriv));
    if_lt_serial = GiNaC::function::register_new(function_options("rd_if_lt", 4)
                                                     .eval_func(if_eval<true>)
                                                     .evalf_func(if_evalf<true>)
                                                     .expl_derivative_func(if_deriv<true>));
    if_le_serial = GiNaC::function::register_new(function_options("rd_if_le", 4)
                                                     .eval_func(if_eval<false>)
                                                     .evalf_func(if_evalf<false>)
                                                     .expl_derivative_func(if_deriv<false>));
    min_serial = GiNaC::function::register_new(function_options("rd_min", 2)
                                                   .eval_func(minmax_eval<false>)
                                                   .evalf_func(minmax_eval<false>)
                                                   .expl_derivative_func(minmax_deriv<false>));
    max_serial = GiNaC::function::register_new(function_options("rd_max", 2)
                                                   .eval_func(minmax_eval<true>)
                                                   .evalf_func(minmax_eval<true>)
                                                   .expl_derivative_func(minmax_deriv<true>));
    step_serial = GiNaC::function::register_new(function_options("rd_step", 1)
                                                    .eval_func(step_eval)
                                                    .evalf_func(step_eval)
                                                    .expl_derivative_func(step_deriv));
    clamp_serial = GiNaC::function::register_new(function_options("rd_clamp", 3)
                                                     .eval_func(clamp_eval)
                                                     .evalf_func(clamp_eval)
                                                     .expl_derivative_func(clamp_deriv));
  }
};

void ensure_registered() {
  static Registration once;  // thread-safe; callers also hold ginac_mutex()
}

}  // namespace

unsigned serial_abs() { return ensure_registered(), abs_serial; }
unsigned serial_sgn() { return ensure_registered(), sgn_serial; }
unsigned serial_if_lt() { return ensure_registered(), if_lt_serial; }
unsigned serial_if_le() { return ensure_registered(), if_le_serial; }
unsigned serial_min() { return ensure_registered(), min_serial; }
unsigned serial_max() { return ensure_registered(), max_serial; }
unsigned serial_step() { return ensure_registered(), step_serial; }
unsigned serial_clamp() { return ensure_registered(), clamp_serial; }

bool has_piecewise(const ex& e) {
  return any_node(e, [](const ex& x) {
    if (!GiNaC::is_a<GiNaC::function>(x)) return false;
    const unsigned s = GiNaC::ex_to<GiNaC::function>(x).get_serial();
    return s == abs_serial || s == sgn_serial || s == if_lt_serial || s == if_le_serial ||
           s == min_serial || s == max_serial || s == step_serial || s == clamp_serial;
  });
}

// ------------------------------------------------------------------------------------------
// Syntax tree -> GiNaC
// ------------------------------------------------------------------------------------------
namespace {

/// Integer powers of numbers whose exact result would exceed this many bits are computed in
/// floating point instead (2^2^2^2^2^2 would otherwise make GiNaC build a 2^65536-bit integer).
constexpr double kMaxExactPowerBits = 4096;

/// GiNaC's number for a literal: integers exact, decimals as floats (as GiNaC's parser did).
/// A decimal exponent beyond the double range is decided here, before CLN would build the exact
/// number 10^e (1e99999999 took seconds and hundreds of MB): too large is an error, too small
/// is zero.
ex number(const std::string& lit) {
  const auto e = lit.find_first_of("eE");
  if (e != std::string::npos) {
    const std::string exponent = lit.substr(e + 1);
    const bool negative = !exponent.empty() && exponent[0] == '-';
    const size_t digits = exponent.find_first_not_of("+-");
    const std::string magnitude = digits == std::string::npos ? "" : exponent.substr(digits);
    if (magnitude.size() > 4 || (!magnitude.empty() && std::stoi(magnitude) > 1000)) {
      if (lit.substr(0, e).find_first_not_of("0.") == std::string::npos) return ex(0);  // 0e±huge
      if (negative) return ex(0);
      throw BadConstant{"is beyond the range of double-precision numbers (about 1.8e308)", lit, true};
    }
  }
  return GiNaC::numeric(lit.c_str());
}

ex parameter(double v) {
  if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0)
    return GiNaC::numeric(static_cast<long>(v));
  return GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
}

/// Largest |integer exponent| of a non-constant base: GiNaC handles x^n exactly, and a huge n
/// makes it build numbers such as 4^n when it normalises (x/4 + 3/2)^n (a fuzzer found
/// n = 3.3e30 running for minutes in GMP).
constexpr double kMaxSymbolicExponent = 4096;

/// A constant's value as a real number (itself when it is one; evalf of an expression without
/// symbols, such as e, pi^2 or 3^e); else the expression unchanged. The powers inside a constant
/// went through power() already, so evaluating it stays within kMaxExactPowerBits.
ex value_if_constant(const ex& e) {
  if (real_number(e)) return e;
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) return e;
  const ex v = e.evalf();
  return real_number(v) ? v : e;
}

ex power(const ex& b, const ex& p) {
  if (real_number(b) && num(b).is_zero() && real_number(p) && num(p).is_negative())
    throw std::domain_error("division by zero");  // 0^negative, before GiNaC (see Product)
  if (!real_number(b) && real_number(p) && num(p).is_integer() &&
      std::fabs(num(p).to_double()) > kMaxSymbolicExponent)
    throw std::domain_error("the integer exponent " + to_text(p) + " of a non-constant base is larger than " +
                            fmt(kMaxSymbolicExponent) + " in magnitude");
  // Integer or not: a power of numbers too large to represent exactly (a float tower such as
  // 2.^4.^2.^2.1 made CLN ask for a 70 GB block) is computed in double precision. Constants that
  // are not numbers yet (3666666^e, pi^…) count by their values (value_if_constant): GiNaC keeps such a power
  // unevaluated and evalf later builds it exactly (a fuzzer found 6336^33333333336316666668^3666666^e
  // asking CLN for 1e18 bytes).
  const ex bv = value_if_constant(b), pv = value_if_constant(p);
  if (real_number(bv) && real_number(pv) && !num(bv).is_zero()) {
    const double bits = std::fabs(num(pv).to_double()) *
                        std::max(1.0, std::fabs(std::log2(std::fabs(num(bv).to_double()))));
    if (bits > kMaxExactPowerBits) {
      const double v = std::pow(num(bv).to_double(), num(pv).to_double());
      if (!std::isfinite(v) && v != 0.0)
        throw BadConstant{"evaluates to " + fmt(v), to_text(b) + "^" + to_text(p), true};
      return GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
    }
  }
  return GiNaC::pow(b, p);
}

ex call(const AstNode& node, const std::vector<ex>& a) {
  switch (node.fn) {
    case Fn::Sin: return GiNaC::sin(a[0]);
    case Fn::Cos: return GiNaC::cos(a[0]);
    case Fn::Tan: return GiNaC::tan(a[0]);
    case Fn::Asin: return GiNaC::asin(a[0]);
    case Fn::Acos: return GiNaC::acos(a[0]);
    case Fn::Atan: return GiNaC::atan(a[0]);
    case Fn::Atan2: return GiNaC::atan2(a[0], a[1]);
    case Fn::Sinh: return GiNaC::sinh(a[0]);
    case Fn::Cosh: return GiNaC::cosh(a[0]);
    case Fn::Tanh: return GiNaC::tanh(a[0]);
    case Fn::Asinh: return GiNaC::asinh(a[0]);
    case Fn::Acosh: return GiNaC::acosh(a[0]);
    case Fn::Atanh: return GiNaC::atanh(a[0]);
    case Fn::Exp: return GiNaC::exp(a[0]);
    case Fn::Log: return GiNaC::log(a[0]);
    case Fn::Sqrt: return GiNaC::sqrt(a[0]);
    case Fn::Pow: return power(a[0], a[1]);
    case Fn::Abs: return make_abs(a[0]);
    // min/max: the first argument wins ties (a <= b for min, a >= b for max).
    case Fn::Min: return make_min(a[0], a[1]);
    case Fn::Max: return make_max(a[0], a[1]);
    // step(x) = 1 for x >= 0, else 0.
    case Fn::Step: return make_step(a[0]);
    // clamp(x, lo, hi) = lo if x < lo, hi if x > hi, else x (x itself at either bound).
    case Fn::Clamp: return make_clamp(a[0], a[1], a[2]);
    case Fn::If:
      switch (node.cmp) {
        case Cmp::Lt: return make_if(true, a[0], a[1], a[2], a[3]);
        case Cmp::Le: return make_if(false, a[0], a[1], a[2], a[3]);
        case Cmp::Gt: return make_if(true, a[1], a[0], a[2], a[3]);
        case Cmp::Ge: return make_if(false, a[1], a[0], a[2], a[3]);
      }
  }
  return 0;
}

/// Builds the GiNaC expression of every node (children first). On a GiNaC or BadConstant
/// exception while building node i, `failed` = i and the exception is rethrown.
std::vector<ex> build(const ParseResult& fe, const std::vector<GiNaC::realsymbol>& syms,
                      std::size_t& failed) {
  ensure_registered();
  std::vector<ex> out(fe.nodes.size());
  std::vector<ex> args;
  for (std::size_t i = 0; i < fe.nodes.size(); ++i) {
    const AstNode& node = fe.nodes[i];
    args.clear();
    for (std::uint32_t k = 0; k < node.count; ++k) args.push_back(out[fe.kids[node.first + k]]);
    auto flag = [&](std::uint32_t k) { return fe.flags[node.first + k] != 0; };
    try {
      switch (node.kind) {
        case AstKind::Number: out[i] = number(node.text); break;
        case AstKind::Variable: out[i] = syms[node.index]; break;
        case AstKind::Parameter: out[i] = parameter(node.value); break;
        case AstKind::Pi: out[i] = GiNaC::Pi; break;
        case AstKind::E: out[i] = GiNaC::exp(ex(1)); break;
        case AstKind::Sum: {
          GiNaC::exvector terms;
          terms.reserve(args.size());
          for (std::uint32_t k = 0; k < node.count; ++k)
            terms.push_back(flag(k) ? -args[k] : args[k]);
          out[i] = GiNaC::add(terms);
          break;
        }
        case AstKind::Product: {
          // Left to right, as written: a/b*c = (a/b)*c. Factors are collected into one
          // product (linear cost); a divisor d becomes d^-1, which GiNaC evaluates at once (a
          // constant zero divisor throws "division by zero" here, at this node).
          GiNaC::exvector factors;
          factors.reserve(args.size());
          for (std::uint32_t k = 0; k < node.count; ++k) {
            // A zero divisor is reported before GiNaC sees it: GiNaC throws from inside its
            // allocation and leaks the half-built power object.
            if (flag(k) && real_number(args[k]) && num(args[k]).is_zero())
              throw std::domain_error("division by zero");
            factors.push_back(flag(k) ? GiNaC::pow(args[k], -1) : args[k]);
          }
          out[i] = GiNaC::mul(factors);
          break;
        }
        case AstKind::Neg: out[i] = -args[0]; break;
        case AstKind::Power: out[i] = power(args[0], args[1]); break;
        case AstKind::Call: out[i] = call(node, args); break;
      }
    } catch (...) {
      failed = i;
      throw;
    }
  }
  return out;
}

[[noreturn]] void fail_node(const std::string& text, const AstNode* node, const std::string& what,
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

bool is_bad_constant(const ex& e) {
  if (has_symbol(e)) return false;
  try {
    constant_value(e);
    return false;
  } catch (const BadConstant&) {
    return true;
  }
}

}  // namespace

Symbolic lower_symbolic(const std::string& text, const ParseResult& fe,
                        const std::vector<GiNaC::realsymbol>& syms, const ExpressionOptions& opt) {
  const int derivative_order = opt.derivative_order;
  const int n = static_cast<int>(syms.size());
  const std::string param_hint = parameter_hint(fe);
  Symbolic s;
  ex& value = s.value;
  std::size_t failed = fe.nodes.size();
  try {
    value = build(fe, syms, failed).back();
  } catch (const BadConstant& bc) {
    fail_bad_constant(text, fe, syms, bc);
  } catch (const std::exception& err) {
    std::string msg = err.what();
    const AstNode* node = failed < fe.nodes.size() ? &fe.nodes[failed] : nullptr;
    if (msg.find("division by zero") != std::string::npos)
      fail_node(text, node, "division by zero: a constant sub-expression is infinite", param_hint);
    if (msg.find("integer exponent") != std::string::npos)
      fail_node(text, node, msg + " (hint: rewrite the power)", param_hint);
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

  // Hessian entries for detecting a constant Hessian when it was not requested. Piecewise
  // expressions never qualify (their Hessian is piecewise constant, not constant).
  const bool try_quadratic = opt.specialize && derivative_order >= 1 &&
                             static_cast<int>(s.used.size()) <= kMaxQuadratic &&
                             !has_piecewise(value);
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

void fail_bad_constant(const std::string& text, const ParseResult& fe,
                       const std::vector<GiNaC::realsymbol>& syms, const BadConstant& bc) {
  // Rebuild the node expressions (linear) and point at the first, i.e. innermost, bad one.
  const AstNode* node = nullptr;
  std::size_t failed = fe.nodes.size();
  try {
    const std::vector<ex> exs = build(fe, syms, failed);
    for (std::size_t i = 0; i < fe.nodes.size() && !node; ++i)
      if (fe.nodes[i].located && is_bad_constant(exs[i])) node = &fe.nodes[i];
  } catch (...) {
    if (failed < fe.nodes.size()) node = &fe.nodes[failed];
  }
  std::string what = bc.infinite ? "a constant sub-expression is infinite ('" + bc.constant +
                                       "' " + bc.what + ")"
                                 : "non-numeric leftover: a constant sub-expression " + bc.what;
  fail_node(text, node, what, parameter_hint(fe));
}

}  // namespace expr_detail
}  // namespace refdyn
