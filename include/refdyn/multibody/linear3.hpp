#pragma once
/// 3-vectors and 3×3 matrices over a scalar S, as plain arrays with named operations (no
/// expression templates: the order of every sum and product is the one written, which keeps
/// GiNaC expressions as short as the formulas and double results reproducible).
///
///     Vec3T<S> = (x, y, z),  Mat3T<S> = row-major (R00 R01 R02 R10 … R22)
///     add(a, b) = a + b,  sub(a, b) = a − b,  scale(a, s) = a s,  dot(a, b) = aᵀb,
///     cross(a, b) = a × b,  mul(R, v) = R v,  mul(A, B) = A B,  transpose(A) = Aᵀ,
///     skew(a) = [a]× (skew(a) v = a × v)
#include "refdyn/multibody/scalar.hpp"
#include "refdyn/multibody/spatial.hpp"

#include <array>
#include <type_traits>

namespace refdyn::multibody {

template <class S> using Vec3T = std::array<S, 3>;
template <class S> using Mat3T = std::array<S, 9>;  ///< row-major

template <class S> Vec3T<S> zero3() { const S z = from_double<S>(0.0); return {z, z, z}; }
template <class S> Mat3T<S> zero33() {
  const S z = from_double<S>(0.0);
  return {z, z, z, z, z, z, z, z, z};
}
template <class S> Mat3T<S> identity3() {
  const S z = from_double<S>(0.0), o = from_double<S>(1.0);
  return {o, z, z, z, o, z, z, z, o};
}
/// A double vector / matrix of the model as S constants.
template <class S> Vec3T<S> lift(const Vec3& v) { return {from_double<S>(v.x()), from_double<S>(v.y()), from_double<S>(v.z())}; }
template <class S> Mat3T<S> lift(const Mat3& A) {
  Mat3T<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[3 * i + j] = from_double<S>(A(i, j));
  return r;
}

template <class S> Vec3T<S> add(const Vec3T<S>& a, const Vec3T<S>& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
template <class S> Vec3T<S> sub(const Vec3T<S>& a, const Vec3T<S>& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
template <class S> Vec3T<S> scale(const Vec3T<S>& a, const std::type_identity_t<S>& s) { return {a[0] * s, a[1] * s, a[2] * s}; }
template <class S> S dot(const Vec3T<S>& a, const Vec3T<S>& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
template <class S> Vec3T<S> cross(const Vec3T<S>& a, const Vec3T<S>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
template <class S> Vec3T<S> mul(const Mat3T<S>& R, const Vec3T<S>& v) {
  return {R[0] * v[0] + R[1] * v[1] + R[2] * v[2], R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
          R[6] * v[0] + R[7] * v[1] + R[8] * v[2]};
}
template <class S> Mat3T<S> mul(const Mat3T<S>& A, const Mat3T<S>& B) {
  Mat3T<S> C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
  return C;
}
template <class S> Mat3T<S> transpose(const Mat3T<S>& A) {
  Mat3T<S> T;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) T[3 * i + j] = A[3 * j + i];
  return T;
}
template <class S> Mat3T<S> skew(const Vec3T<S>& a) {
  const S z = from_double<S>(0.0);
  return {z, -a[2], a[1], a[2], z, -a[0], -a[1], a[0], z};
}
template <class S> Mat3T<S> add(const Mat3T<S>& A, const Mat3T<S>& B) {
  Mat3T<S> C;
  for (int k = 0; k < 9; ++k) C[k] = A[k] + B[k];
  return C;
}
template <class S> Mat3T<S> scale(const Mat3T<S>& A, const std::type_identity_t<S>& s) {
  Mat3T<S> C;
  for (int k = 0; k < 9; ++k) C[k] = A[k] * s;
  return C;
}

/// A pose X = (R, p): x_A = R x_B + p; X_AB · X_BC = (R_AB R_BC, R_AB p_BC + p_AB).
template <class S>
struct PoseT {
  Mat3T<S> R = identity3<S>();
  Vec3T<S> p = zero3<S>();
  PoseT operator*(const PoseT& o) const { return {mul(R, o.R), add(mul(R, o.p), p)}; }
};

/// Elementary poses: rotations about x, y, z by a and the translation by p.
template <class S> PoseT<S> rot_x(const S& a) {
  const S c = cos_of(a), s = sin_of(a), z = from_double<S>(0.0), o = from_double<S>(1.0);
  return {{o, z, z, z, c, -s, z, s, c}, zero3<S>()};
}
template <class S> PoseT<S> rot_y(const S& a) {
  const S c = cos_of(a), s = sin_of(a), z = from_double<S>(0.0), o = from_double<S>(1.0);
  return {{c, z, s, z, o, z, -s, z, c}, zero3<S>()};
}
template <class S> PoseT<S> rot_z(const S& a) {
  const S c = cos_of(a), s = sin_of(a), z = from_double<S>(0.0), o = from_double<S>(1.0);
  return {{c, -s, z, s, c, z, z, z, o}, zero3<S>()};
}
template <class S> PoseT<S> translation(const Vec3T<S>& p) { return {identity3<S>(), p}; }

}  // namespace refdyn::multibody
