#pragma once
/// Symbolic scalar expressions for task constraints, compiled to a fast evaluation tape.
///
/// A constraint such as `(x(E)/a)^2 + (y(E)/b)^2 - 1` is parsed once (a front end that resolves
/// names, fixes precedence and builds a syntax tree), turned into a GiNaC expression, its
/// gradient and Hessian are derived exactly (GiNaC), and value + gradient + Hessian are compiled
/// into one flat instruction tape over doubles with common-subexpression elimination shared
/// across all entries. Evaluation is an interpreter loop over that tape: no GiNaC, no virtual
/// calls, no heap allocation.
///
/// Syntax
///   numbers      2, 0.5, .5, 1e-3
///   operators    + - * / ^ (also **), unary + -, parentheses. Usual precedence: ^ binds
///                tighter than unary minus (-x^2 = -(x^2)) and is right-associative
///                (a^b^c = a^(b^c)); * and / are left-associative (a/b*c = (a/b)*c).
///   functions    sin cos tan asin acos atan atan2(y,x) sinh cosh tanh asinh acosh atanh
///                exp log sqrt pow(a,b)
///                piecewise (see "Kinks" below):
///                abs(x)
///                min(a,b) max(a,b)
///                step(x)           1 for x >= 0, else 0
///                clamp(x,lo,hi)    lo if x < lo, hi if x > hi, else x (expects lo <= hi)
///                if(cond, a, b)    a where cond holds, else b
///   conditions   only as the first argument of if(): exactly one comparison `u < v`,
///                `u <= v`, `u > v` or `u >= v` between two expressions. No chained
///                comparisons (a < b < c), no == or !=, no and/or (nest if() instead), and no
///                comparisons anywhere else. The comparison is made on the two evaluated sides.
///   constants    pi, e (= exp(1)); a variable or parameter of the same name shadows them
///   variables    any listed name: a plain identifier (`t`, `x`) or a call-like name
///                `name(arg)` such as `x(E)`, `vx(E)`, `q(psi1)`. Whitespace inside is ignored:
///                `x( E )` is the variable "x(E)". A call-like name that is listed as a variable
///                wins over a function of the same name.
///   parameters   identifiers given numeric values; substituted as constants before
///                differentiation (integers exactly, other values as IEEE doubles). A
///                parameter may make a variable disappear (`k*t` with k = 0): see
///                used_variables() and referenced_variables().
///
/// Kinks (abs, min, max, step, clamp, if): derivatives are exact and finite on both sides and
/// at the switching point itself; no NaN at a kink. At the switching point the value, gradient
/// and Hessian all come from the same one branch (one-sided derivatives of that branch):
///   abs(x)        d/dx = +1 at x = 0 (right-sided), d²/dx² = 0
///   min(a,b)      a where a <= b: at a tie the first argument's derivatives
///   max(a,b)      a where a >= b: at a tie the first argument's derivatives
///   step(x)       1 at x = 0; derivative 0 everywhere (including at 0)
///   clamp(x,l,h)  x at x = l and at x = h (derivative 1: the inside branch)
///   if(u < v, a, b)   b at u = v;  if(u <= v, a, b)  a at u = v
///   if(u > v, a, b)   b at u = v;  if(u >= v, a, b)  a at u = v
/// The selection itself is not differentiated (d/dx if(c, a, b) = if(c, da/dx, db/dx)), and the
/// branch not taken does not affect the result, even if it is infinite or NaN there:
/// `if(x > 0, log(x), 0)` is 0 with derivative 0 at x = 0. Example: the programmed speed
/// `(1 - cos(pi*min(t, 2)/2))/2` has at t = 2 the derivatives of the rising branch
/// (d/dt = (pi/4) sin(pi) ~ 0, d²/dt² = -pi²/8), just after t = 2 those of the constant one.
/// Such expressions never use the quadratic kernel. text() and the derivative texts print
/// them with the engine's GiNaC names: rd_abs(u), rd_sgn(u) (u >= 0 ? 1 : -1), rd_min(a, b),
/// rd_max(a, b), rd_step(u), rd_clamp(x, lo, hi), rd_if_lt(u, v, a, b) (u < v ? a : b) and
/// rd_if_le(u, v, a, b) (u <= v ? a : b).
///
/// Limits (ExpressionOptions): the text may be at most max_length = 64 KiB long and nest at most
/// max_depth = 256 levels (parentheses, function arguments, unary signs, exponents); both are
/// checked before any recursive work and raise refdyn::Error naming the limit. Within them,
/// construction time and memory grow about linearly with the length of the text (chains of
/// + - * / are n-ary, not nested); symbolic differentiation itself can still grow an
/// expression (a product of n distinct factors has a gradient of n products).
///
/// Thread safety: an Expression is immutable after construction; evaluating one Expression from
/// several threads at once is safe (each call uses its own scratch). Construction uses GiNaC,
/// which is not thread-safe; constructors serialise on an internal mutex, but other GiNaC users
/// in the same process are not covered by it.
///
/// Allocation: evaluate() and value() never allocate for tapes of at most kStackRegisters
/// registers (nor the quadratic kernel); larger tapes allocate once per thread and size, or
/// never with an ExpressionWorkspace sized for the expression (tests/expression_alloc_test.cpp).

#include "refdyn/common/dual.hpp"

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

class Expression;

/// Caller-owned scratch registers for Expression::evaluate. Sized from an expression, it makes
/// evaluation allocation-free whatever the tape size. One workspace per thread; it may be
/// reused for any expression whose register count fits (it grows, allocating, if it does not).
class ExpressionWorkspace {
 public:
  ExpressionWorkspace() = default;
  explicit ExpressionWorkspace(const Expression& e);
  /// Grows (never shrinks) to fit `e`.
  void reserve_for(const Expression& e);
  std::size_t size() const { return registers_.size(); }

 private:
  friend class Expression;
  std::vector<double> registers_;
};

/// Caller-owned dual-number registers for the dual-number Expression::evaluate (as
/// ExpressionWorkspace for the double one): sized from an expression, evaluation does not
/// allocate. One workspace per thread; it grows (allocating) for a larger expression.
class ExpressionDualWorkspace {
 public:
  ExpressionDualWorkspace() = default;
  explicit ExpressionDualWorkspace(const Expression& e);
  /// Grows (never shrinks) to fit `e`.
  void reserve_for(const Expression& e);
  std::size_t size() const { return registers_.size(); }

 private:
  friend class Expression;
  std::vector<JacobianScalar> registers_;
};

/// Construction options beyond the derivative order.
struct ExpressionOptions {
  /// 0 (value only), 1 (+ gradient) or 2 (+ Hessian).
  int derivative_order = 2;
  /// Use a closed-form kernel when the structure allows it instead of interpreting the tape.
  /// Currently: expressions with a constant Hessian (polynomials of degree <= 2 in at most 8
  /// used variables, e.g. ellipse/sphere/plane constraints), evaluated as
  /// value = c0 + xᵀ(b + A x / 2), gradient = b + A x, Hessian = A. The kernel is checked
  /// against the tape at construction. false: always the tape (tests, benchmarks).
  bool specialize = true;
  /// Limits checked before any recursive work (the parser, GiNaC and the compiler recurse over
  /// the expression tree; these bounds keep them far from the stack limit and keep the cost of
  /// construction proportional to the text). Exceeding one throws refdyn::Error naming the
  /// limit, the value found and this option.
  /// Longest accepted text, in bytes (characters). 64 KiB by default.
  std::size_t max_length = 64 * 1024;
  /// Deepest accepted nesting. Each of these opens one level around what it contains: a
  /// parenthesis, a function call's arguments, a unary sign (each '-' of `- - x`) and the
  /// exponent of ^ (a^b^c nests c two levels deep). Chains of + - * / at one level do not nest
  /// (1+1+...+1 has depth 1). 256 by default; raising it far (beyond a few thousand) can
  /// overflow the stack in GiNaC.
  int max_depth = 256;
  /// Also compile ∂ᵏf/∂x_iᵏ (k = extra_derivative_order ≥ 1 along the variable of index
  /// i = extra_derivative_variable), differentiated exactly by GiNaC after the parameters are
  /// substituted, as a second, value-only tape read by Expression::extra_derivative(x); 0: none.
  /// A time function's f''' is k = 3 along t. It is built in the same construction over the same
  /// GiNaC symbols: no new symbols, so expressions built afterwards compile exactly as they would
  /// without it (GiNaC orders the terms of sums and products by hashes of symbol serial numbers,
  /// and the tape's evaluation order follows).
  int extra_derivative_order = 0;
  int extra_derivative_variable = 0;
};

class Expression {
 public:
  /// Parses and compiles `text`.
  /// `variables`: the argument order of evaluate(); names as written in the text (whitespace is
  ///   ignored). `parameters`: named constants. `derivative_order`: 0 (value only),
  ///   1 (+ gradient) or 2 (+ Hessian).
  /// Throws refdyn::Error on a syntax error, an unknown identifier, a bad function call, a
  /// NaN/infinite parameter, a constant sub-expression that is infinite (e.g. division by zero)
  /// or not a real number (e.g. sqrt(-1)), duplicate/ill-formed variable names, a name that is
  /// both a variable and a parameter, or a derivative order outside 0..2.
  Expression(const std::string& text, const std::vector<std::string>& variables,
             const std::map<std::string, double>& parameters = {}, int derivative_order = 2);
  Expression(const std::string& text, const std::vector<std::string>& variables,
             const std::map<std::string, double>& parameters, const ExpressionOptions& options);

  /// Number of variables n (the length of x in evaluate()).
  int num_variables() const;
  /// Variable names in argument order, whitespace-stripped.
  const std::vector<std::string>& variables() const;
  /// Indices of the variables the expression depends on after parameter substitution and
  /// simplification, ascending (gradient sparsity).
  std::vector<int> used_variables() const;
  /// Indices of the variables written in the text, ascending; a superset of used_variables()
  /// (`x + k*t` with k = 0 references t but does not use it). To rebuild an expression over
  /// fewer variables, keep at least these: a name missing from the list is an unknown
  /// identifier even where a parameter cancels it.
  std::vector<int> referenced_variables() const;
  int derivative_order() const;
  /// The source text as given.
  const std::string& source() const;

  /// Value at x (size n). Runs only the value part of the tape.
  double value(const double* x) const;
  /// Value, and optionally the gradient (grad, size n) and Hessian (hess, n×n, symmetric, so
  /// row- and column-major alike). Pass nullptr to skip either. Entries for variables the
  /// expression does not use are written as 0. Requires derivative_order() >= 1 for grad and
  /// >= 2 for hess (else throws Error). Does not allocate if the tape needs at most
  /// kStackRegisters registers; larger tapes use a per-thread buffer that allocates once per
  /// thread and size (use the workspace overload to avoid that).
  void evaluate(const double* x, double& value, double* grad, double* hess) const;
  /// As above with caller-provided scratch: never allocates if `ws` was sized for this
  /// expression (ExpressionWorkspace(expr) or reserve_for(expr)).
  void evaluate(const double* x, double& value, double* grad, double* hess,
                ExpressionWorkspace& ws) const;

  /// The same over dual numbers (common/dual.hpp): x, value, gradient and Hessian are
  /// JacobianScalar, so the derivative parts of value, grad and hess are the exact directional
  /// derivatives along the seeds of x (third derivatives of f included, through the Hessian
  /// tape). Runs the same tape as the double evaluate (never the quadratic kernel); values equal
  /// the double ones to rounding. Comparisons, Sign and Select act on the value parts (the
  /// branch taken is not differentiated, as in the double engine). Same order checks. The
  /// first form uses a per-thread workspace (allocates once per thread and size); the second
  /// never allocates with a workspace sized for this expression; the third takes
  /// register_count() registers from the caller.
  void evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                JacobianScalar* hess) const;
  void evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                JacobianScalar* hess, ExpressionDualWorkspace& ws) const;
  void evaluate(const JacobianScalar* x, JacobianScalar& value, JacobianScalar* grad,
                JacobianScalar* hess, JacobianScalar* registers) const;

  /// ∂ᵏf/∂x_iᵏ at x (size n) as asked for by ExpressionOptions::extra_derivative_order and
  /// extra_derivative_variable. Allocates as value() does. Throws Error for an expression built
  /// without it.
  double extra_derivative(const double* x) const;
  /// That derivative as text (refdyn syntax, as text(); same Error).
  std::string extra_derivative_text() const;

  /// The expression after parameter substitution, in refdyn's expression syntax: parsed again it
  /// is the same function (piecewise ones included). GiNaC's per-process choices are undone where
  /// printing can: operands of sums and products in text order, a sum factor in one orientation
  /// ((a − b) rather than −(b − a)). Where GiNaC itself forms different but equal expressions in
  /// two runs (mixing floating-point and exact numbers, e.g. 6*(u)/(c − 9.0*x) or
  /// u/(c/6 − 1.5*x)) the texts differ too; the compiled numbers never do.
  std::string text() const;
  /// ∂/∂x_i as text ("0" for unused variables). Requires derivative_order() >= 1.
  std::string derivative_text(int i) const;
  /// ∂²/∂x_i∂x_j as text. Requires derivative_order() >= 2.
  std::string second_derivative_text(int i, int j) const;

  /// Diagnostics: number of tape instructions (after CSE and constant folding) and number of
  /// registers one evaluation needs.
  int tape_size() const;
  int register_count() const;
  /// Tape size the same expression would have without common-subexpression elimination (every
  /// occurrence compiled separately); for tests and documentation of the CSE gain. Counting
  /// stops at max(65536, 16 × tape_size()) (derivatives share sub-expressions, and compiling
  /// every occurrence can be exponentially larger): a value at that cap means "at least".
  int tape_size_without_cse() const;
  /// Human-readable listing of the tape (one instruction per line).
  std::string tape_listing() const;
  /// True if evaluation uses the closed-form quadratic kernel (see ExpressionOptions).
  bool is_quadratic() const;

  static constexpr int kStackRegisters = 256;

  struct Impl;
  /// Evaluation entry point chosen at construction (quadratic kernel or tape interpreter);
  /// scratch: registers for the interpreter, nullptr for its own stack buffer.
  using Kernel = void (*)(const Impl& impl, const double* x, double& value, double* grad,
                          double* hess, double* scratch);

 private:
  [[noreturn]] void throw_order_error(bool grad) const;

  std::shared_ptr<const Impl> impl_;
  const Impl* raw_ = nullptr;  // impl_.get(), saves a load in the hot path
  Kernel kernel_ = nullptr;
  int order_ = 0;
};

inline double Expression::value(const double* x) const {
  double v;
  kernel_(*raw_, x, v, nullptr, nullptr, nullptr);
  return v;
}

inline void Expression::evaluate(const double* x, double& value, double* grad,
                                 double* hess) const {
  if ((grad && order_ < 1) || (hess && order_ < 2)) throw_order_error(grad && order_ < 1);
  kernel_(*raw_, x, value, grad, hess, nullptr);
}

}  // namespace refdyn
