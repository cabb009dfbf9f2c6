#pragma once
// Private to the C writer (emit_c.cpp): the generated C as a graph of double operations.
//
//   Tape      the operations (constants, inputs, + − × ÷, negation, calls, conditionals), each
//             node once (hash-consing: equal operations on equal operands are one node, which is
//             the common-subexpression elimination), with structural zeros and ones folded.
//   TS        a scalar that records on the current Tape: the generic multibody core
//             (refdyn/multibody/) instantiated for it writes the recursive algorithms as straight
//             code (the composite-rigid-body M, Newton–Euler c + g) with the model's numbers
//             folded, instead of expanded formulas.
//   FromGinac GiNaC expressions (constraints, forces, poses, parameters) onto the Tape. Operands
//             of sums and products are taken in the order of a structural key computed from the
//             expression itself (numbers, symbol and function names), never from GiNaC's
//             address-seeded hashes, so the Tape — and the C text — is the same in every run.
//   emit()    C statements of chosen outputs: a node used twice or more becomes a `const double
//             tK` temporary, numbered in the Tape's (deterministic) order.
#include "internal.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <tuple>
#include <vector>

namespace refdyn::symbolic_detail {

class Tape {
 public:
  enum class Op : int { Const, Leaf, Add, Sub, Mul, Div, Neg, Call, Cond, Pow };
  struct Node {
    Op op = Op::Const;
    std::vector<int> args;
    double value = 0;   ///< Const: the value; Cond: 1 for <, 0 for <=; Pow: the integer exponent
    std::string text;   ///< Leaf: the C expression; Call: the function name
  };
  int constant(double v);
  int leaf(const std::string& text);
  int add(int a, int b);
  int sub(int a, int b);
  int mul(int a, int b);
  int div(int a, int b);
  int neg(int a);
  int call(const std::string& name, std::vector<int> args);
  int cond(bool strict, int a, int b, int c, int d);
  int pow(int a, long p);  ///< a^p, integer p ≥ 2 (kept for the LaTeX and text writers)
  const Node& node(int id) const { return nodes_[static_cast<std::size_t>(id)]; }
  bool is_const(int id, double v) const { return node(id).op == Op::Const && node(id).value == v; }
  std::size_t size() const { return nodes_.size(); }

 private:
  int intern(Node n);
  std::vector<Node> nodes_;
  std::map<std::tuple<int, std::vector<int>, std::uint64_t, std::string>, int> index_;
};

/// The Tape TS records on (set by TapeScope; one thread at a time: the generator holds the GiNaC
/// mutex).
Tape*& current_tape();
struct TapeScope {
  explicit TapeScope(Tape& t) : prev(current_tape()) { current_tape() = &t; }
  ~TapeScope() { current_tape() = prev; }
  Tape* prev;
};

struct TS {
  int id = -1;
  TS() : id(current_tape()->constant(0.0)) {}
  explicit TS(int i) : id(i) {}
};
inline TS operator+(TS a, TS b) { return TS(current_tape()->add(a.id, b.id)); }
inline TS operator-(TS a, TS b) { return TS(current_tape()->sub(a.id, b.id)); }
inline TS operator*(TS a, TS b) { return TS(current_tape()->mul(a.id, b.id)); }
inline TS operator/(TS a, TS b) { return TS(current_tape()->div(a.id, b.id)); }
inline TS operator-(TS a) { return TS(current_tape()->neg(a.id)); }
inline TS& operator+=(TS& a, TS b) { return a = a + b; }
inline TS& operator-=(TS& a, TS b) { return a = a - b; }
inline TS& operator*=(TS& a, TS b) { return a = a * b; }

/// Canonical views of GiNaC expressions. GiNaC orders the operands of sums and products by
/// hashes seeded with addresses, and some of its automatic simplifications follow that order: a
/// sum may come as x − y in one run and as −(y − x) in another, and (a/2 + b)² as ¼(a + 2b)² in
/// one run and as is in another (power::eval takes the content of a sum out when its first
/// term's coefficient allows it). Canon writes every expression as e = c · ê, a numeric
/// coefficient c times a normalized ê whose key is computed from the expression itself (numbers,
/// symbol and function names, the keys of the operands, sorted for sums and products; a sum is
/// normalized by the coefficient of its first term in key order): both are the same in every
/// run. The writers take operands in key order and build ê from the keys, so their texts are
/// too.
class Canon {
 public:
  struct View {
    GiNaC::numeric coef = 1;
    std::uint64_t key = 0;
  };
  const View& operator()(const ex& e);
  /// The terms of a sum in key order with their coefficients relative to the first (r₀ = 1):
  /// sum = c · Σ rᵢ t̂ᵢ.
  std::vector<std::pair<GiNaC::numeric, ex>> terms(const ex& sum);
  /// The non-numeric factors of a product in key order.
  std::vector<ex> factors(const ex& product);

 private:
  std::map<ex, View, GiNaC::ex_is_less> memo_;
};

/// GiNaC expressions onto the Tape (memoized; `leaf` names the symbols), through Canon.
/// keep_powers: integer powers as Pow nodes (LaTeX, expression text), else products (C).
class FromGinac {
 public:
  FromGinac(Tape& tape, std::function<std::string(const GiNaC::symbol&)> leaf, bool keep_powers = false)
      : tape_(tape), leaf_(std::move(leaf)), keep_powers_(keep_powers) {}
  int operator()(const ex& e);
  TS ts(const ex& e) { return TS((*this)(e)); }

 private:
  int norm(const ex& e);  ///< the node of ê
  int scaled(const GiNaC::numeric& c, int v);
  int power(int base, long p);
  Tape& tape_;
  std::function<std::string(const GiNaC::symbol&)> leaf_;
  bool keep_powers_;
  Canon canon_;
  std::map<std::uint64_t, int> memo_;
  std::map<ex, int, GiNaC::ex_is_less> whole_;
};

/// C statements for the outputs (lhs text, node): temporaries (nodes used twice or more; with
/// cse false, none: every output printed whole), then one line per output. Counts the
/// temporaries and the operations (+ − × ÷ and calls) written.
std::string emit(const Tape& tape, const std::vector<std::pair<std::string, int>>& outputs, bool cse,
                 const std::string& indent, long& temporaries, long& operations);

/// A node as a text of refdyn's expression language: whole, no temporaries; `^` for powers, abs,
/// min, max, step, clamp and if() for the piecewise functions.
std::string expression_text(const Tape& tape, int id);

/// Texts of the expression language with auxiliaries (the JSON writer): a sub-expression used
/// twice or more whose text has `shared` characters or more, or any of `single` or more, is
/// written once as an auxiliary aux(k) (k from 1, numbered in the order they are first needed;
/// each one's text names only earlier ones), so the texts grow with the graph, not with its
/// expansion into a tree.
class AuxiliaryTexts {
 public:
  /// `roots`: every node that will be printed (for counting uses).
  AuxiliaryTexts(const Tape& tape, const std::vector<int>& roots, std::size_t shared = 80, std::size_t single = 2000);
  std::string operator()(int id);
  const std::vector<std::string>& auxiliaries() const { return aux_; }

 private:
  std::string body(int id);              ///< the node's text, its operands by name or text
  std::string ref(int id, int level);    ///< an operand: its name, or its text (parenthesized)
  const Tape& t_;
  std::size_t shared_, single_;
  std::vector<int> uses_;
  std::vector<std::string> name_;
  std::vector<std::string> aux_;
  std::map<int, std::string> memo_;
};

}  // namespace refdyn::symbolic_detail

namespace refdyn::multibody {
template <>
struct ScalarTraits<symbolic_detail::TS> {
  using T = symbolic_detail::TS;
  static T from_double(double v) { return T(symbolic_detail::current_tape()->constant(v)); }
  static T sin(const T& x) { return T(symbolic_detail::current_tape()->call("sin", {x.id})); }
  static T cos(const T& x) { return T(symbolic_detail::current_tape()->call("cos", {x.id})); }
  static T sqrt(const T& x) { return T(symbolic_detail::current_tape()->call("sqrt", {x.id})); }
  static bool is_zero(const T& x) { return symbolic_detail::current_tape()->is_const(x.id, 0.0); }
};
}  // namespace refdyn::multibody
