#pragma once
/// The symbolic form of a constraint, force element, surface or function of time: its formulas
/// as texts of the expression language (expression.hpp), which `refdyn generate`
/// (symbolic.hpp) parses into GiNaC, chains through the symbolic kinematics and differentiates.
///
/// Variables a text may use (the generator binds them):
///   t                          time
///   q(j), qd(j)                joint coordinate and velocity of joint j (by name)
///   x(P), y(P), z(P)           world coordinates of point P
///   vx(P), vy(P), vz(P)        its world velocity
///   R11(P) … R33(P)            the world orientation of the body carrying P (row, column)
///   z(k), zdot(k)              force elements only: the element's own state k (0, 1, …) and
///                              its rate (the rates are the element's `state_rates`)
///   NAME, d_NAME               force elements only: a function of time the element names in
///                              `functions` (e.g. a drive profile) and its exact derivative
/// plus named parameters (`parameters`), which the generated code keeps as symbols.
/// Numbers are written with 17 significant digits, so a text reproduces the doubles exactly.
#include <array>
#include <map>
#include <string>
#include <vector>

namespace refdyn {

struct SymbolicForm {
  std::vector<std::string> rows;                  ///< one formula per row (constraint) or output
  std::map<std::string, double> parameters;       ///< named constants the texts use
  std::map<std::string, std::string> functions;   ///< named functions of t (force elements)
  std::vector<std::string> state_rates;           ///< ż of the element's states (force elements)
  std::vector<int> joints;                        ///< force elements: the joint of each row
  /// The texts contain scenario texts of numbers (Number::text): the generator binds the
  /// scenario's parameters, which those texts name, besides `parameters`.
  bool scenario_texts = false;
};

/// A form of rows (and the parameters they name).
inline SymbolicForm symbolic_rows(std::vector<std::string> rows, std::map<std::string, double> parameters = {}) {
  SymbolicForm f;
  f.rows = std::move(rows);
  f.parameters = std::move(parameters);
  return f;
}

/// A number of a constraint, force element or function of time together with the scenario text
/// it was written as when that text is an expression (a parameter name, `2*pi`,
/// `0.5*cos(45*deg)`); empty for a plain literal or a number computed in C++. The symbolic form
/// writes "(text)" for it (symbolic_number), so the generated equations keep the scenario's
/// names; the numeric code reads only the value. Converts to and from double.
struct Number {
  double value = 0.0;
  std::string text;  ///< the expression as written in the scenario; empty: a number
  Number(double v = 0.0) : value(v) {}  // NOLINT: implicit, a double is a Number without a text
  Number(double v, std::string t) : value(v), text(std::move(t)) {}
  operator double() const { return value; }  // NOLINT: implicit, the numeric code reads the value
};

/// Three Numbers (a centre, a direction, an axis as written).
using Number3 = std::array<Number, 3>;

/// Whether any of the numbers carries a scenario text (for SymbolicForm::scenario_texts).
template <class... N>
bool any_text(const N&... n) {
  return (!n.text.empty() || ...);
}

/// A double as a text of the expression language that parses back to the same double
/// (17 significant digits, parenthesised when negative).
std::string symbolic_number(double v);
/// "(text)" when the number was written as an expression, else symbolic_number(n.value).
std::string symbolic_number(const Number& n);

}  // namespace refdyn
