#pragma once
// Private to the fast double kernels (src/multibody/rnea.cpp, crba.cpp, aba.cpp): 4-lane vectors,
// 3×3 matrices and rigid-body inertias in registers, sin/cos four at a time. Not installed. Every
// helper is force-inlined (REFDYN_INLINE), so the kernels in the three files compile as they did
// in one file. The speed notes are in kernels.hpp.
#include "refdyn/multibody/model.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__GNUC__) || defined(__clang__)
#define REFDYN_INLINE inline __attribute__((always_inline))
#define REFDYN_ALIGNED_64 __attribute__((aligned(64)))  // a function's first byte on a 64-byte boundary
#else
#define REFDYN_INLINE inline
#define REFDYN_ALIGNED_64
#endif

// With AVX (the default build uses -march=native) a 4-lane vector is one register and one
// instruction per operation; without it the same code runs on a plain struct of four doubles.
#if (defined(__GNUC__) || defined(__clang__)) && defined(__AVX__)
#define REFDYN_V4_SIMD 1
#endif

namespace refdyn::kernels {

// ---- 4-lane vectors ----------------------------------------------------------------------------

#if REFDYN_V4_SIMD
typedef double v4 __attribute__((vector_size(4 * sizeof(double))));
typedef std::int64_t v4l __attribute__((vector_size(4 * sizeof(double))));

/// Lanes (i, j, k, l) of the concatenation (a, b) (indices 4–7 pick from b).
template <int i, int j, int k, int l>
REFDYN_INLINE v4 shuf2(v4 a, v4 b) {
#if defined(__clang__) || __GNUC__ >= 12
  return __builtin_shufflevector(a, b, i, j, k, l);
#else
  return __builtin_shuffle(a, b, v4l{i, j, k, l});
#endif
}
#else
struct v4 {
  double e[4];
  double& operator[](int k) { return e[k]; }
  double operator[](int k) const { return e[k]; }
};
REFDYN_INLINE v4 operator+(v4 a, v4 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]}; }
REFDYN_INLINE v4 operator-(v4 a, v4 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]}; }
REFDYN_INLINE v4 operator*(v4 a, v4 b) { return {a[0] * b[0], a[1] * b[1], a[2] * b[2], a[3] * b[3]}; }
REFDYN_INLINE v4 operator-(v4 a) { return {-a[0], -a[1], -a[2], -a[3]}; }
REFDYN_INLINE v4& operator+=(v4& a, v4 b) { return a = a + b; }
REFDYN_INLINE v4& operator-=(v4& a, v4 b) { return a = a - b; }
template <int i, int j, int k, int l>
REFDYN_INLINE v4 shuf2(v4 a, v4 b) {
  auto pick = [&](int n) { return n < 4 ? a[n] : b[n - 4]; };
  return {pick(i), pick(j), pick(k), pick(l)};
}
#endif
template <int i, int j, int k, int l>
REFDYN_INLINE v4 shuf(v4 a) {
  return shuf2<i, j, k, l>(a, a);
}

/// x, y, z, 0 from three consecutive doubles.
REFDYN_INLINE v4 ld3(const double* p) { return v4{p[0], p[1], p[2], 0.0}; }
REFDYN_INLINE v4 ld3(const Vec3& a) { return ld3(a.data()); }
/// Four consecutive doubles; only where the fourth still lies inside the same object.
REFDYN_INLINE v4 ld4(const double* p) {
  v4 a;
  std::memcpy(&a, p, sizeof a);
  return a;
}
REFDYN_INLINE void st3(v4 a, double* p) {
  p[0] = a[0];
  p[1] = a[1];
  p[2] = a[2];
}
REFDYN_INLINE void st3(v4 a, Vec3& o) { st3(a, o.data()); }
/// Writes four doubles; only where the fourth is rewritten afterwards, inside the same object.
REFDYN_INLINE void st4(v4 a, double* p) { std::memcpy(p, &a, sizeof a); }
REFDYN_INLINE v4 splat(double s) { return v4{s, s, s, s}; }
template <int k>
REFDYN_INLINE v4 bc(v4 a) {
  return shuf<k, k, k, k>(a);
}
REFDYN_INLINE v4 yzx(v4 a) { return shuf<1, 2, 0, 3>(a); }
REFDYN_INLINE v4 cross(v4 a, v4 b) { return yzx(a * yzx(b) - yzx(a) * b); }
REFDYN_INLINE double dot3(v4 a, v4 b) {
  const v4 m = a * b;
  return m[0] + m[1] + m[2];
}
/// ez × x = (−x.y, x.x, 0) and x × ez = (x.y, −x.x, 0).
REFDYN_INLINE v4 x_cross_ez(v4 x) {
  return shuf2<1, 0, 4, 4>(x, v4{0.0, 0.0, 0.0, 0.0}) * v4{1.0, -1.0, 1.0, 1.0};
}
REFDYN_INLINE v4 ez(double s) { return splat(s) * v4{0.0, 0.0, 1.0, 0.0}; }

/// 3×3 matrix as three columns.
struct M3 {
  v4 c0, c1, c2;
};
REFDYN_INLINE v4 mul(const M3& A, v4 x) { return A.c0 * bc<0>(x) + A.c1 * bc<1>(x) + A.c2 * bc<2>(x); }
REFDYN_INLINE M3 transpose(const M3& A) {
  const v4 lo = shuf2<0, 4, 1, 5>(A.c0, A.c1);  // a0x a1x a0y a1y
  const v4 hi = shuf2<2, 6, 3, 7>(A.c0, A.c1);  // a0z a1z . .
  return {shuf2<0, 1, 4, 7>(lo, A.c2), shuf2<2, 3, 5, 7>(lo, A.c2), shuf2<0, 1, 6, 7>(hi, A.c2)};
}
/// Columns of a Mat3 (column-major); the padding lanes of c0, c1 hold the next column's x.
REFDYN_INLINE M3 ld(const Mat3& R) {
  const double* d = R.data();
  return {ld4(d), ld4(d + 3), ld3(d + 6)};
}
/// Columns of an SE3's rotation: the last one may over-read into p (same object).
REFDYN_INLINE M3 ld_rot(const SE3& X) {
  const double* d = X.R.data();
  return {ld4(d), ld4(d + 3), ld4(d + 6)};
}
REFDYN_INLINE void st(const M3& A, Mat3& R) {
  double* d = R.data();
  st4(A.c0, d);
  st4(A.c1, d + 3);
  st3(A.c2, d + 6);
}

// ---- sin/cos -----------------------------------------------------------------------------------

/// sin and cos of four angles: Cody–Waite reduction by π/2 (three-part constant, exact products
/// for |x| < 2^29) and Cephes' minimax polynomials on [−π/4, π/4] (about 1 ulp); branch-free,
/// one vector instruction per step. Angles with |x| ≥ 1e6 (or not finite) take std::sin/cos.
constexpr int kBlock = 4;

#if REFDYN_V4_SIMD
REFDYN_INLINE void sincos4(v4 x, double* s, double* c) {
  constexpr double two_over_pi = 0.636619772367581343075535053490057;
  constexpr double P1 = 1.57079625129699707031e+00;  // π/2 = P1 + P2 + P3
  constexpr double P2 = 7.54978941586159635335e-08;
  constexpr double P3 = 5.39030285815811905290e-15;
  constexpr double shifter = 6755399441055744.0;  // 1.5·2^52: x + shifter rounds x to an integer
  const v4 t = x * two_over_pi + shifter;
  const v4 kd = t - shifter;
  const v4l quadrant = (v4l)(t);  // bit cast; low bits: round(2x/π) mod 4
  const v4 r = ((x - kd * P1) - kd * P2) - kd * P3;
  const v4 z = r * r;
  const v4 ps = ((((1.58962301576546568060e-10 * z - 2.50507477628578072866e-8) * z +
                   2.75573136213857245213e-6) * z - 1.98412698295895385996e-4) * z +
                 8.33333333332211858878e-3) * z - 1.66666666666666307295e-1;
  const v4 pc = ((((-1.13585365213876817300e-11 * z + 2.08757008419747316778e-9) * z -
                   2.75573141792967388112e-7) * z + 2.48015872888517045348e-5) * z -
                 1.38888888888730564116e-3) * z + 4.16666666666665929218e-2;
  const v4 sr = r + r * z * ps;
  const v4 cr = (1.0 - 0.5 * z) + z * z * pc;
  const v4l swap = (quadrant & 1) != 0;
  const v4 s_abs = swap ? cr : sr, c_abs = swap ? sr : cr;
  const v4l sv = (v4l)(s_abs) ^ ((quadrant & 2) << 62);
  const v4l cv = (v4l)(c_abs) ^ (((quadrant + 1) & 2) << 62);
  std::memcpy(s, &sv, sizeof sv);
  std::memcpy(c, &cv, sizeof cv);
  const v4l xa = (v4l)(x) & 0x7fffffffffffffffLL;
  const v4l small = (v4)(xa) < 1e6;  // false for NaN
  if ((small[0] & small[1] & small[2] & small[3]) == 0)
    for (int k = 0; k < kBlock; ++k)
      if (!(std::abs(x[k]) < 1e6)) {
        s[k] = std::sin(x[k]);
        c[k] = std::cos(x[k]);
      }
}
#else
REFDYN_INLINE void sincos4(v4 x, double* s, double* c) {
  for (int k = 0; k < kBlock; ++k) {
    s[k] = std::sin(x[k]);
    c[k] = std::cos(x[k]);
  }
}
#endif

// ---- rigid-body inertias -----------------------------------------------------------------------

/// Inertia (m, h, I columns) in registers.
struct In {
  double m;
  v4 h;
  M3 I;
};
REFDYN_INLINE In ld(const Inertia& I) {
  return {I.m, ld4(I.h.data()), {ld4(I.I.data()), ld4(I.I.data() + 3), ld3(I.I.data() + 6)}};
}
REFDYN_INLINE void st(const In& a, Inertia& I) {
  I.m = a.m;
  st4(a.h, I.h.data());  // the fourth double is I(0,0), rewritten next
  st(a.I, I.I);
}
REFDYN_INLINE void add(In& a, const In& b) {
  a.m += b.m;
  a.h += b.h;
  a.I.c0 += b.I.c0;
  a.I.c1 += b.I.c1;
  a.I.c2 += b.I.c2;
}

/// The inertia `a` (given in B) expressed in A, for X_AB = (R, p):
///   I_A = R I Rᵀ + 2 (k·p) 1 − (p kᵀ + k pᵀ),  k = R h + ½ m p,   h_A = R h + m p.
REFDYN_INLINE In transform(const In& a, const M3& R, v4 p) {
  const v4 Rh = mul(R, a.h);
  const v4 k = Rh + splat(0.5 * a.m) * p;
  const double d = 2.0 * dot3(k, p);
  const M3 A{mul(R, a.I.c0), mul(R, a.I.c1), mul(R, a.I.c2)};  // R I
  const M3 Rt = transpose(R);
  const v4 dp = splat(d);
  In o;
  o.m = a.m;
  o.h = Rh + splat(a.m) * p;
  o.I.c0 = mul(A, Rt.c0) - p * bc<0>(k) - k * bc<0>(p) + dp * v4{1.0, 0.0, 0.0, 0.0};
  o.I.c1 = mul(A, Rt.c1) - p * bc<1>(k) - k * bc<1>(p) + dp * v4{0.0, 1.0, 0.0, 0.0};
  o.I.c2 = mul(A, Rt.c2) - p * bc<2>(k) - k * bc<2>(p) + dp * v4{0.0, 0.0, 1.0, 0.0};
  return o;
}

}  // namespace refdyn::kernels
