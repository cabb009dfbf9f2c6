// Formula (formula.hpp): the text-writing scalar whose law<Formula> instantiations give the
// symbolic forms of constraint kinds, surfaces and force elements.
#include "refdyn/expression/formula.hpp"

#include "refdyn/common/error.hpp"

#include <cmath>
#include <limits>

namespace refdyn {

namespace {
constexpr double kNotConstant = std::numeric_limits<double>::quiet_NaN();
thread_local FormulaScope* innermost = nullptr;
}  // namespace

Formula::Formula(double v) : value_(v) {
  if (v == 0.0) text_ = "0";
  else if (v == 1.0) text_ = "1";
  else text_ = symbolic_number(v);  // negative numbers come parenthesised: an atom
}

Formula::Formula(std::string text, Binding binding) : text_(std::move(text)), binding_(binding), value_(kNotConstant) {}

Formula Formula::variable(std::string name) { return Formula(std::move(name), kAtom); }

Formula Formula::number(const Number& n) {
  if (n.text.empty()) return Formula(n.value);
  if (FormulaScope* s = FormulaScope::current()) s->scenario_texts = true;
  return Formula(symbolic_number(n), kAtom);
}

std::string operand_text(const Formula& f, Formula::Binding context) {
  return f.binding() < context ? "(" + f.text() + ")" : f.text();
}

Formula operator+(const Formula& a, const Formula& b) {
  if (a.is_zero()) return b;
  if (b.is_zero()) return a;
  return Formula(a.text() + " + " + operand_text(b, Formula::kNegation), Formula::kSum);
}

Formula operator-(const Formula& a, const Formula& b) {
  if (b.is_zero()) return a;
  if (a.is_zero()) return -b;
  return Formula(a.text() + " - " + operand_text(b, Formula::kProduct), Formula::kSum);
}

Formula operator-(const Formula& a) {
  if (a.is_zero()) return a;
  return Formula("-" + operand_text(a, Formula::kProduct), Formula::kNegation);
}

Formula operator*(const Formula& a, const Formula& b) {
  if (a.is_zero() || b.is_zero()) return Formula(0.0);
  if (a.is_one()) return b;
  if (b.is_one()) return a;
  return Formula(operand_text(a, Formula::kNegation) + "*" + operand_text(b, Formula::kProduct), Formula::kProduct);
}

Formula operator/(const Formula& a, const Formula& b) {
  if (b.is_one()) return a;
  if (a.is_zero()) return a;
  return Formula(operand_text(a, Formula::kNegation) + "/" + operand_text(b, Formula::kPower), Formula::kProduct);
}

Formula pow(const Formula& x, const Formula& p) {
  return Formula(operand_text(x, Formula::kAtom) + "^" + operand_text(p, Formula::kAtom), Formula::kPower);
}

Formula call(const char* name, std::initializer_list<Formula> arguments) {
  std::string text = std::string(name) + "(";
  bool first = true;
  for (const Formula& a : arguments) {
    text += (first ? "" : ", ") + a.text();
    first = false;
  }
  return Formula(text + ")", Formula::kAtom);
}

FormulaScope::FormulaScope() : outer_(innermost) { innermost = this; }
FormulaScope::~FormulaScope() { innermost = outer_; }
FormulaScope* FormulaScope::current() { return innermost; }

TimeValueFormula time_value(const TimeFunction& f, const Formula&) {
  std::optional<SymbolicForm> form = f.symbolic();
  if (!form || form->rows.size() != 1) throw NoSymbolicForm{"the function of time " + f.describe() + " has no symbolic form"};
  FormulaScope* scope = FormulaScope::current();
  std::string name = "f";
  if (scope) {
    name += std::to_string(scope->functions.size());
    scope->functions[name] = form->rows[0];
    scope->scenario_texts = scope->scenario_texts || form->scenario_texts;
    for (const auto& [key, value] : form->parameters) {
      auto [it, inserted] = scope->parameters.emplace(key, value);
      if (!inserted && !(it->second == value))
        throw Error("symbolic form: two functions of time name the parameter '" + key + "' with different values");
    }
  }
  return {Formula("(" + form->rows[0] + ")", Formula::kAtom), Formula::variable("d_" + name),
          Formula::variable("dd_" + name)};
}

}  // namespace refdyn
