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
}  // namespace refdyn::symbolic_detail

namespace refdyn::multibody {
template <>
struct ScalarTraits<GiNaC::ex> {
  static GiNaC::ex from_double(double v) { return symbolic_detail::number(v); }
  static GiNaC::ex sin(const GiNaC::ex& x) { return GiNaC::sin(x); }
  static GiNaC::ex cos(const GiNaC::ex& x) { return GiNaC::cos(x); }
  static GiNaC::ex sqrt(const GiNaC::ex& x) { return GiNaC::sqrt(x); }
  static bool is_zero(const GiNaC::ex& x) { return x.is_zero(); }
};
}  // namespace refdyn::multibody
