#pragma once
/// Dual numbers (common/dual.hpp) as a scalar of the generic multibody core: multibody::Dual<N>
/// with its functions, and ScalarTraits<Dual<N>>.
#include "refdyn/common/dual.hpp"
#include "refdyn/multibody/scalar.hpp"

namespace refdyn::multibody {

using ad::Dual;
using ad::chain;
using ad::sin;
using ad::cos;
using ad::sqrt;
using ad::exp;
using ad::log;
using ad::tan;
using ad::asin;
using ad::acos;
using ad::atan;
using ad::sinh;
using ad::cosh;
using ad::tanh;
using ad::asinh;
using ad::acosh;
using ad::atanh;
using ad::abs;
using ad::atan2;
using ad::pow;

template <int N>
struct ScalarTraits<Dual<N>> {
  static Dual<N> from_double(double v) { return Dual<N>(v); }
  static Dual<N> sin(const Dual<N>& x) { return multibody::sin(x); }
  static Dual<N> cos(const Dual<N>& x) { return multibody::cos(x); }
  static Dual<N> sqrt(const Dual<N>& x) { return multibody::sqrt(x); }
  static bool is_zero(const Dual<N>& x) {
    if (x.v != 0.0) return false;
    for (int k = 0; k < N; ++k)
      if (x.d[k] != 0.0) return false;
    return true;
  }
};

}  // namespace refdyn::multibody
