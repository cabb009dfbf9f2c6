#pragma once
/// Formula: a scalar whose arithmetic writes text of the expression language (symbolic_form.hpp).
/// It is the instantiation of a law<S> — a constraint kind's (constraints/law.hpp), a surface's,
/// a force element's (forces/force_elements.hpp) — that gives the symbolic form `refdyn generate`
/// reads, so that form is derived from the law the numeric code runs instead of written beside
/// it (as Drake's systems are instantiated for symbolic::Expression).
///
///     q(j), qd(j), x(P), t …      Formula::variable("q(q1)")
///     a scenario number           param<S>(n): n.value for double and dual numbers (the same
///                                 arithmetic as before), "(text)" for a Formula where the
///                                 scenario wrote an expression (a parameter name), so the
///                                 generated code keeps the names
///     a function of time          time_value(f, t): "(f's text)", and f' as the generator's
///                                 d_NAME of the function registered as NAME
///
/// Arithmetic simplifies structurally only (x + 0, x·1, x·0, 0 − x), so a text is as long as the
/// formula the law writes. The generator parses the text into GiNaC, which normalises it.
/// While a FormulaScope lives on a thread, the Formulas made there record into it whether a
/// scenario text was used and which functions of time (with their parameters) a text names.
#include "refdyn/expression/symbolic_form.hpp"
#include "refdyn/expression/time_function.hpp"

#include <initializer_list>
#include <map>
#include <string>
#include <type_traits>

namespace refdyn {

class Formula {
 public:
  Formula(double v = 0.0);  // NOLINT: implicit, as a double converts to the other scalars
  /// A variable of the expression language, as the generator names it ("q(q1)", "vx(E)", "t").
  static Formula variable(std::string name);
  /// n as its scenario text where it has one (recorded in the FormulaScope), else its value.
  static Formula number(const Number& n);
  const std::string& text() const { return text_; }
  bool is_zero() const { return value_ == 0.0; }
  bool is_one() const { return value_ == 1.0; }

  friend Formula operator+(const Formula& a, const Formula& b);
  friend Formula operator-(const Formula& a, const Formula& b);
  friend Formula operator*(const Formula& a, const Formula& b);
  friend Formula operator/(const Formula& a, const Formula& b);
  friend Formula operator-(const Formula& a);
  Formula& operator+=(const Formula& b) { return *this = *this + b; }
  Formula& operator-=(const Formula& b) { return *this = *this - b; }
  Formula& operator*=(const Formula& b) { return *this = *this * b; }
  Formula& operator/=(const Formula& b) { return *this = *this / b; }

  /// How tightly the text binds (a weaker operand is parenthesised).
  enum Binding : int { kSum = 1, kNegation = 2, kProduct = 3, kPower = 4, kAtom = 5 };
  Formula(std::string text, Binding binding);
  Binding binding() const { return binding_; }

 private:
  std::string text_;
  Binding binding_ = kAtom;
  double value_ = 0.0;  ///< the value of a Formula made from a double; NaN for any other text
};

/// The text of f, parenthesised when it binds weaker than `context`.
std::string operand_text(const Formula& f, Formula::Binding context);
/// name(arguments): the functions of the expression language over Formulas.
Formula call(const char* name, std::initializer_list<Formula> arguments);

inline Formula sin(const Formula& x) { return call("sin", {x}); }
inline Formula cos(const Formula& x) { return call("cos", {x}); }
inline Formula tan(const Formula& x) { return call("tan", {x}); }
inline Formula asin(const Formula& x) { return call("asin", {x}); }
inline Formula acos(const Formula& x) { return call("acos", {x}); }
inline Formula atan(const Formula& x) { return call("atan", {x}); }
inline Formula sinh(const Formula& x) { return call("sinh", {x}); }
inline Formula cosh(const Formula& x) { return call("cosh", {x}); }
inline Formula tanh(const Formula& x) { return call("tanh", {x}); }
inline Formula exp(const Formula& x) { return call("exp", {x}); }
inline Formula log(const Formula& x) { return call("log", {x}); }
inline Formula sqrt(const Formula& x) { return call("sqrt", {x}); }
inline Formula abs(const Formula& x) { return call("abs", {x}); }
inline Formula atan2(const Formula& y, const Formula& x) { return call("atan2", {y, x}); }
Formula pow(const Formula& x, const Formula& p);

/// What the Formulas made on this thread while the scope lives have used: whether a scenario
/// text (SymbolicForm::scenario_texts), the functions of time by name (SymbolicForm::functions)
/// and their parameters. Scopes nest (the innermost records).
class FormulaScope {
 public:
  FormulaScope();
  ~FormulaScope();
  FormulaScope(const FormulaScope&) = delete;
  FormulaScope& operator=(const FormulaScope&) = delete;
  static FormulaScope* current();

  bool scenario_texts = false;
  std::map<std::string, double> parameters;
  std::map<std::string, std::string> functions;

 private:
  FormulaScope* outer_;
};

/// Thrown by time_value over Formulas for a function of time without a symbolic form (the
/// derivation then gives no form: the generator says which element has none).
struct NoSymbolicForm {
  std::string what;
};

/// f, f', f'' at the Formula t: "(f's text)" (its parameters recorded in the scope), and f', f''
/// as the variables d_NAME, dd_NAME of the function, registered in the scope as NAME (the
/// generator binds NAME and d_NAME for force elements; a constraint's row uses f itself).
struct TimeValueFormula {
  Formula f, df, ddf;
};
TimeValueFormula time_value(const TimeFunction& f, const Formula& t);

/// A scenario number as the scalar S: its value for double and the dual numbers (so their
/// arithmetic is unchanged), Formula::number for a Formula.
template <class S>
auto param(const Number& n) {
  if constexpr (std::is_same_v<S, Formula>) return Formula::number(n);
  else return n.value;
}

}  // namespace refdyn
