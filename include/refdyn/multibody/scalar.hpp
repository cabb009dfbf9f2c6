#pragma once
/// Scalar traits of the generic multibody core: what the templates over a scalar S need beyond
/// + − × (sin, cos, sqrt, conversion from a double, and a test for a structural zero).
///
///     ScalarTraits<S>::from_double(v)   the constant v as an S (exact for double and duals)
///     ScalarTraits<S>::sin(x), cos(x), sqrt(x)
///     ScalarTraits<S>::is_zero(x)       true only when x is exactly (structurally) zero; the
///                                       core uses it to skip terms that would only grow a
///                                       symbolic expression, never to change a numeric result
///
/// Provided here for double; dual.hpp provides them for refdyn::multibody::Dual<N>; the code
/// generator provides them for GiNaC::ex (src/symbolic/ginac_scalar.hpp, not installed).
#include <cmath>

namespace refdyn::multibody {

template <class S>
struct ScalarTraits;  // specialised per scalar type

template <>
struct ScalarTraits<double> {
  static double from_double(double v) { return v; }
  static double sin(double x) { return std::sin(x); }
  static double cos(double x) { return std::cos(x); }
  static double sqrt(double x) { return std::sqrt(x); }
  static bool is_zero(double x) { return x == 0.0; }
};

/// Short forms of the traits, for the templates.
template <class S> S from_double(double v) { return ScalarTraits<S>::from_double(v); }
template <class S> S sin_of(const S& x) { return ScalarTraits<S>::sin(x); }
template <class S> S cos_of(const S& x) { return ScalarTraits<S>::cos(x); }
template <class S> S sqrt_of(const S& x) { return ScalarTraits<S>::sqrt(x); }
template <class S> bool is_zero(const S& x) { return ScalarTraits<S>::is_zero(x); }

}  // namespace refdyn::multibody
