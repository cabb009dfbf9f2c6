#pragma once
/// GiNaC expressions as a scalar of the generic multibody core (refdyn/multibody/scalar.hpp):
/// the code generator instantiates the kinematics and Newton–Euler templates with S = GiNaC::ex.
/// Private to the generator (GiNaC is not a public dependency of the installed headers).
#include "refdyn/multibody/scalar.hpp"

#include <ginac/ginac.h>

namespace refdyn::symbolic_detail {
/// A double as a GiNaC number, exactly (an integer or the rational m·2^e).
GiNaC::ex number(double v);
/// e with its floating-point numbers replaced by their double values as exact rationals.
GiNaC::ex exact(const GiNaC::ex& e);
/// A numeric model constant (an entry of a fixed rotation, the sine of a constant angle): 0 and ±1
/// exactly, any other value v as the opaque rd_const(v) (v exact), which GiNaC neither
/// distributes over sums nor combines with other numbers, so that a dense rotation (a rounded π
/// in a joint origin leaves entries of 1e-12 where 0 was meant) costs a product per entry
/// instead of a copy of every sum it multiplies. The writers print it as the number v.
GiNaC::ex model_constant(double v);
/// The serial of rd_const.
unsigned serial_constant();
/// sin, cos and sqrt for the generic core: GiNaC's, except that a constant argument GiNaC cannot
/// evaluate exactly (sin(1.57079632679)) gives the double result as a model constant instead of
/// an unevaluated function that never cancels.
GiNaC::ex sin_of(const GiNaC::ex& x);
GiNaC::ex cos_of(const GiNaC::ex& x);
GiNaC::ex sqrt_of(const GiNaC::ex& x);
}  // namespace refdyn::symbolic_detail

namespace refdyn::multibody {
template <>
struct ScalarTraits<GiNaC::ex> {
  static GiNaC::ex from_double(double v) { return symbolic_detail::number(v); }
  static GiNaC::ex sin(const GiNaC::ex& x) { return symbolic_detail::sin_of(x); }
  static GiNaC::ex cos(const GiNaC::ex& x) { return symbolic_detail::cos_of(x); }
  static GiNaC::ex sqrt(const GiNaC::ex& x) { return symbolic_detail::sqrt_of(x); }
  static bool is_zero(const GiNaC::ex& x) { return x.is_zero(); }
};
}  // namespace refdyn::multibody
