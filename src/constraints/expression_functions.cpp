// Functions of time and texts written in the expression language (expression.hpp): the
// expression time function f(t) with exact derivatives up to the third, and the total time
// derivative of a constraint expression as a text (`differentiate: true`).
#include "refdyn/common/error.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_function.hpp"

namespace refdyn {

namespace {

ExpressionOptions with_third_derivative() {
  ExpressionOptions o;
  o.derivative_order = 2;
  o.extra_derivative_order = 3;
  o.extra_derivative_variable = 0;
  return o;
}

/// f, f', f'' from one tape (value, gradient, Hessian in t); f''' from the expression's second,
/// value-only tape of d³f/dt³, differentiated by GiNaC (ExpressionOptions::extra_derivative_order).
class ExpressionTimeFunction final : public TimeFunction {
 public:
  ExpressionTimeFunction(const std::string& text, const std::map<std::string, double>& params)
      : text_(text), params_(params), expr_(text, {"t"}, params, with_third_derivative()) {}
  std::optional<SymbolicForm> symbolic() const override { return symbolic_rows({text_}, params_); }
  TimeValue eval(double t) const override {
    TimeValue v;
    expr_.evaluate(&t, v.f, &v.df, &v.ddf);
    v.dddf = expr_.extra_derivative(&t);
    return v;
  }
  std::string describe() const override { return text_; }
 private:
  std::string text_;
  std::map<std::string, double> params_;
  Expression expr_;
};

}  // namespace

std::string differentiate_expression_text(const Model& model, const std::string& name, const std::string& text,
                                          const std::map<std::string, double>& parameters) {
  // Every variable of every order, with the name of its rate ("" for the jerks: order 4).
  std::vector<std::string> names, rates;
  const char* axes[] = {"x", "y", "z"};
  const char* level[] = {"", "v", "a", "j"};
  for (const std::string& p : model.point_name)
    for (int l = 0; l < 4; ++l)
      for (const char* a : axes) {
        names.push_back(std::string(level[l]) + a + "(" + p + ")");
        rates.push_back(l < 3 ? std::string(level[l + 1]) + a + "(" + p + ")" : std::string());
      }
  const char* joint_level[] = {"q", "qd", "qdd", "qddd"};
  for (const std::string& j : model.joint_name)
    for (int l = 0; l < 4; ++l) {
      names.push_back(std::string(joint_level[l]) + "(" + j + ")");
      rates.push_back(l < 3 ? std::string(joint_level[l + 1]) + "(" + j + ")" : std::string());
    }
  names.push_back("t");
  rates.push_back("1");
  std::unique_ptr<Expression> f;
  try {
    f = std::make_unique<Expression>(text, names, parameters, 1);
  } catch (const Error& e) {
    throw Error("constraint '" + name + "': " + e.what());
  }
  std::string out;
  for (int k : f->used_variables()) {
    const std::string d = f->derivative_text(k);
    if (d == "0") continue;
    if (rates[k].empty())
      throw Error("constraint '" + name + "': differentiate: the expression involves the jerk " + names[k] +
                  ", whose time derivative (order 4) refdyn does not take (hint: differentiate a row of order "
                  "position, velocity or acceleration)");
    if (!out.empty()) out += " + ";
    out += rates[k] == "1" ? "(" + d + ")" : "(" + d + ")*" + rates[k];
  }
  return out.empty() ? "0" : out;
}

TimeFunctionPtr expression_time_function(const std::string& text, const std::map<std::string, double>& parameters) {
  try {
    return std::make_shared<ExpressionTimeFunction>(text, parameters);
  } catch (const Error& e) {
    throw Error(std::string("time function: ") + e.what());
  }
}

}  // namespace refdyn
