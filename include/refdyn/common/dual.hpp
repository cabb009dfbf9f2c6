#pragma once
/// Forward-mode dual numbers with N directions, no heap:
///
///     x = v + Σ_k d_k ε_k,   ε_k ε_l = 0,   so  f(x) = f(v) + f'(v) Σ_k d_k ε_k
///
/// Seeding the inputs with directions gives exact directional derivatives of anything computed
/// through the generic core: N = 1 for a time derivative along the motion (the jerk route seeds
/// q with q̇, q̇ with q̈, q̈ with q⃛ = 0), N = n_x (or chunks of a fixed N) for a Jacobian, N = n_p
/// for parameter sensitivities. N is a compile-time constant, so a Dual<N> is a flat array of
/// N + 1 doubles and the operations unroll (bench/dual_bench.cpp compares it with Eigen's
/// AutoDiffScalar, README "Dual numbers").
///
/// In the lowest layer (common/) so that every layer can compute over it (the expression tape,
/// the multibody core, the constraints); multibody/dual.hpp adds the generic core's scalar
/// traits and names it multibody::Dual.
#include <array>
#include <cmath>

namespace refdyn::ad {


template <int N>
struct Dual {
  static_assert(N >= 1, "a dual number needs at least one direction");
  double v;                        ///< value
  std::array<double, N> d;         ///< derivatives along the N directions

  Dual() : v(0.0), d{} {}
  Dual(double value) : v(value), d{} {}  // NOLINT: constants convert implicitly, as in a + 2
  /// value with derivative `dk` along direction k (others 0).
  static Dual variable(double value, int k, double dk = 1.0) {
    Dual r(value);
    r.d[k] = dk;
    return r;
  }

  Dual& operator+=(const Dual& b) {
    v += b.v;
    for (int k = 0; k < N; ++k) d[k] += b.d[k];
    return *this;
  }
  Dual& operator-=(const Dual& b) {
    v -= b.v;
    for (int k = 0; k < N; ++k) d[k] -= b.d[k];
    return *this;
  }
  Dual& operator*=(const Dual& b) { return *this = *this * b; }

  friend Dual operator+(const Dual& a, const Dual& b) {
    Dual r(uninitialized);
    r.v = a.v + b.v;
    for (int k = 0; k < N; ++k) r.d[k] = a.d[k] + b.d[k];
    return r;
  }
  friend Dual operator-(const Dual& a, const Dual& b) {
    Dual r(uninitialized);
    r.v = a.v - b.v;
    for (int k = 0; k < N; ++k) r.d[k] = a.d[k] - b.d[k];
    return r;
  }
  friend Dual operator-(const Dual& a) {
    Dual r(uninitialized);
    r.v = -a.v;
    for (int k = 0; k < N; ++k) r.d[k] = -a.d[k];
    return r;
  }
  /// (a + a' ε)(b + b' ε) = ab + (a' b + a b') ε
  friend Dual operator*(const Dual& a, const Dual& b) {
    Dual r(uninitialized);
    r.v = a.v * b.v;
    for (int k = 0; k < N; ++k) r.d[k] = a.d[k] * b.v + a.v * b.d[k];
    return r;
  }
  /// a / b = a/b + (a' − (a/b) b')/b ε
  friend Dual operator/(const Dual& a, const Dual& b) {
    Dual r(uninitialized);
    r.v = a.v / b.v;
    const double ib = 1.0 / b.v;
    for (int k = 0; k < N; ++k) r.d[k] = (a.d[k] - r.v * b.d[k]) * ib;
    return r;
  }

 private:
  struct Uninitialized {};
  static constexpr Uninitialized uninitialized{};
  explicit Dual(Uninitialized) {}  // the operations fill every entry
};

/// f(v + d ε) = f(v) + f'(v) d ε with f'(v) given.
template <int N>
Dual<N> chain(double fv, double dfv, const Dual<N>& x) {
  Dual<N> r = x;
  r.v = fv;
  for (int k = 0; k < N; ++k) r.d[k] *= dfv;
  return r;
}
template <int N> Dual<N> sin(const Dual<N>& x) { return chain(std::sin(x.v), std::cos(x.v), x); }
template <int N> Dual<N> cos(const Dual<N>& x) { return chain(std::cos(x.v), -std::sin(x.v), x); }
template <int N> Dual<N> sqrt(const Dual<N>& x) {
  const double s = std::sqrt(x.v);
  return chain(s, 0.5 / s, x);
}

template <int N> Dual<N> exp(const Dual<N>& x) {
  const double e = std::exp(x.v);
  return chain(e, e, x);
}
template <int N> Dual<N> log(const Dual<N>& x) { return chain(std::log(x.v), 1.0 / x.v, x); }
template <int N> Dual<N> tan(const Dual<N>& x) {
  const double t = std::tan(x.v);
  return chain(t, 1.0 + t * t, x);
}
template <int N> Dual<N> asin(const Dual<N>& x) { return chain(std::asin(x.v), 1.0 / std::sqrt(1.0 - x.v * x.v), x); }
template <int N> Dual<N> acos(const Dual<N>& x) { return chain(std::acos(x.v), -1.0 / std::sqrt(1.0 - x.v * x.v), x); }
template <int N> Dual<N> atan(const Dual<N>& x) { return chain(std::atan(x.v), 1.0 / (1.0 + x.v * x.v), x); }
template <int N> Dual<N> sinh(const Dual<N>& x) { return chain(std::sinh(x.v), std::cosh(x.v), x); }
template <int N> Dual<N> cosh(const Dual<N>& x) { return chain(std::cosh(x.v), std::sinh(x.v), x); }
template <int N> Dual<N> tanh(const Dual<N>& x) {
  const double t = std::tanh(x.v);
  return chain(t, 1.0 - t * t, x);
}
template <int N> Dual<N> asinh(const Dual<N>& x) { return chain(std::asinh(x.v), 1.0 / std::sqrt(x.v * x.v + 1.0), x); }
template <int N> Dual<N> acosh(const Dual<N>& x) { return chain(std::acosh(x.v), 1.0 / std::sqrt(x.v * x.v - 1.0), x); }
template <int N> Dual<N> atanh(const Dual<N>& x) { return chain(std::atanh(x.v), 1.0 / (1.0 - x.v * x.v), x); }
/// |x|: derivative sign(x) (at 0 the right derivative, +1, as the interpreter's Sign).
template <int N> Dual<N> abs(const Dual<N>& x) { return chain(std::fabs(x.v), x.v >= 0.0 ? 1.0 : -1.0, x); }
/// atan2(y, x): d = (x dy − y dx)/(x² + y²).
template <int N> Dual<N> atan2(const Dual<N>& y, const Dual<N>& x) {
  Dual<N> r(std::atan2(y.v, x.v));
  const double inv = 1.0 / (x.v * x.v + y.v * y.v);
  for (int k = 0; k < N; ++k) r.d[k] = (x.v * y.d[k] - y.v * x.d[k]) * inv;
  return r;
}
/// x^c for a constant exponent c: c x^(c−1) dx.
template <int N> Dual<N> pow(const Dual<N>& x, double c) {
  return chain(std::pow(x.v, c), c == 0.0 ? 0.0 : c * std::pow(x.v, c - 1.0), x);
}
/// x^y: y x^(y−1) dx + x^y log(x) dy (the log term only where dy ≠ 0, so x ≤ 0 with a constant
/// exponent stays finite).
template <int N> Dual<N> pow(const Dual<N>& x, const Dual<N>& y) {
  const double p = std::pow(x.v, y.v);
  Dual<N> r(p);
  const double dx = y.v == 0.0 ? 0.0 : y.v * std::pow(x.v, y.v - 1.0);
  for (int k = 0; k < N; ++k) r.d[k] = dx * x.d[k] + (y.d[k] != 0.0 ? p * std::log(x.v) * y.d[k] : 0.0);
  return r;
}

}  // namespace refdyn::ad

namespace refdyn {
/// Directions per sweep of the engine's exact Jacobians ∂f/∂x (reference dynamics, force
/// elements, constraints): a Jacobian of n_x columns takes ⌈2n / kJacobianDirections⌉ full
/// sweeps (the force-state columns only evaluate the force elements). Eight: the derivative
/// part of a Dual<8> is one 512-bit vector, and 2n ≤ 8 (up to 4 DOF, the paper's arm) takes one
/// sweep; measured with bench/implicit_bench (bench/README.md, "Implicit integration").
inline constexpr int kJacobianDirections = 8;
using JacobianScalar = ad::Dual<kJacobianDirections>;
}  // namespace refdyn
