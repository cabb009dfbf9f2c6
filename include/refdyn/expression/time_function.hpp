#pragma once
/// Scalar functions of time with exact first, second and third derivatives: prescribed
/// trajectories z_a(t), drive profiles ψ_dr(t), programmed speeds s(t), joint torques τ(t).
/// (f''' is what the time derivative of a rheonomic constraint's γ needs: eval_dual below.)

#include "refdyn/common/dual.hpp"
#include "refdyn/expression/symbolic_form.hpp"

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace refdyn {

struct TimeValue {
  double f = 0, df = 0, ddf = 0;  ///< f(t), f'(t), f''(t)
  double dddf = 0;                ///< f'''(t), exact as f' and f''
};

class TimeFunction {
 public:
  virtual ~TimeFunction() = default;
  virtual TimeValue eval(double t) const = 0;
  virtual std::string describe() const = 0;
  /// f(t) as a text of the expression language in t (symbolic_form.hpp), for `refdyn generate`;
  /// none if the function has no closed form.
  virtual std::optional<SymbolicForm> symbolic() const { return std::nullopt; }
};
using TimeFunctionPtr = std::shared_ptr<const TimeFunction>;

/// f(t) = c.
TimeFunctionPtr constant(double c);
/// f(t) = Σ c_k t^k (coefficients from t⁰ upward).
TimeFunctionPtr polynomial(std::vector<double> coefficients);
/// f(t) = offset + amplitude·sin(ω t + phase).
TimeFunctionPtr sinusoid(double amplitude, double omega, double phase = 0.0, double offset = 0.0);
/// Smooth raised-cosine excursion from f0 of height df and period T: f0 + df·(1 − cos(2πt/T))/2.
/// Starts with zero velocity (the spec's z_a(t)).
TimeFunctionPtr raised_cosine(Number f0, Number df, Number period);
/// Cycloidal rise of height `rise` over [t0, t0 + duration] from f0 (zero velocity and
/// acceleration at both ends); constant before and after:
/// f = f0 + rise·(τ − sin(2πτ)/(2π)), τ = (t − t0)/duration ∈ [0, 1].
TimeFunctionPtr cycloidal(Number rise, Number duration, Number f0 = 0.0, Number t0 = 0.0);

/// f(t) given as an expression in `t` and named parameters, e.g. "z0 + dz*(1 - cos(2*pi*t/T))/2";
/// f', f'' and f''' are exact (GiNaC). Syntax: expression.hpp, including abs, min, max, step, clamp and
/// if(t < T, a, b), whose derivatives are finite one-sided values at the switching point (e.g.
/// "(1 - cos(pi*min(t, 2)/2))/2" at t = 2). A parameter that cancels t (amp*sin(t), amp = 0)
/// gives a constant function. Throws Error for a text that does not parse.
TimeFunctionPtr expression_time_function(const std::string& text, const std::map<std::string, double>& parameters = {});

/// f, f', f'' at a dual time t = t.v + Σ_k t.d_k ε_k (any ad::Dual<N>): each a dual number whose
/// derivative parts are the next derivative (f', f'', f''') times t.d_k, exact. An unseeded t
/// (every t.d_k = 0) gives derivative parts that are exactly +0, as Dual<N>(f.f) would.
template <int N>
struct TimeValueDualN {
  ad::Dual<N> f, df, ddf;
};
using TimeValueDual = TimeValueDualN<kJacobianDirections>;
template <int N>
TimeValueDualN<N> eval_dual(const TimeFunction& f, const ad::Dual<N>& t) {
  const TimeValue v = f.eval(t.v);
  bool seeded = false;
  for (double d : t.d) seeded = seeded || d != 0.0;
  if (!seeded) return {ad::Dual<N>(v.f), ad::Dual<N>(v.df), ad::Dual<N>(v.ddf)};
  return {ad::chain(v.f, v.df, t), ad::chain(v.df, v.ddf, t), ad::chain(v.ddf, v.dddf, t)};
}

/// f, f', f'' at t over the scalar of t: TimeValue for a double, TimeValueDualN for a dual
/// number (eval_dual). The one spelling the laws of constraint kinds and force elements use.
inline TimeValue time_value(const TimeFunction& f, double t) { return f.eval(t); }
template <int N>
TimeValueDualN<N> time_value(const TimeFunction& f, const ad::Dual<N>& t) {
  return eval_dual(f, t);
}

}  // namespace refdyn
