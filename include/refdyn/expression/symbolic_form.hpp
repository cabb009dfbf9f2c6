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
};

/// A form of rows (and the parameters they name).
inline SymbolicForm symbolic_rows(std::vector<std::string> rows, std::map<std::string, double> parameters = {}) {
  SymbolicForm f;
  f.rows = std::move(rows);
  f.parameters = std::move(parameters);
  return f;
}

/// The scenario texts of an object's numbers, recorded while the scenario builds it (a parameter
/// name, `2*pi`, `0.5*cos(45*deg)`: any number not written as a plain literal), so that the
/// generated formulas keep the names: each number token of a symbolic form that
/// symbolic_number(v) printed for a recorded v is replaced by "(text)". A value recorded with
/// two different texts stays a number (which name would be a guess).
struct SymbolicInputs {
  std::vector<std::pair<double, std::string>> recorded;  ///< (value, text) in reading order
  std::map<std::string, double> parameters;              ///< the scenario's parameters
  void apply(SymbolicForm& form) const;
};

/// A double as a text of the expression language that parses back to the same double
/// (17 significant digits, parenthesised when negative).
std::string symbolic_number(double v);

}  // namespace refdyn
