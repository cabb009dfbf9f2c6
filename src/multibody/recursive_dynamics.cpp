#include "refdyn/multibody/recursive_dynamics.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>

// Speed notes. These kernels are the fast route; tests/trace_dynamics_test.cpp checks them
// against the independent trace route to 1e-10 and bench/dynamics_bench.cpp times them against
// Orocos KDL (see bench/README.md).
//  - 3-vectors live in 4-lane SIMD registers (GCC/Clang vector extensions: one AVX instruction
//    per vector operation, a cross product is four; without AVX a struct of four doubles). The
//    fourth lane is padding: no result lane 0–2 ever reads it, so it may hold anything.
//  - Joints whose axis is ±z of the joint frame (every DH joint) are special-cased: S is a unit
//    vector, so S·F is one lane of F, S q̇ adds to one lane of v, v ×m S q̇ is a lane swap. The
//    sign of the axis is folded into q̇, q̈ and τ. X = P·Rz(q) costs four vector operations.
//  - sin/cos of the joint angles are evaluated four at a time (vectorised polynomial).
//  - The parent's quantities are carried in registers when the parent is the previous body
//    (every serial chain) instead of making a store→load round trip through Data; trees fall
//    back to memory.
//  - RNEA is Featherstone's, in body frames, gravity as a base acceleration, with the body
//    force written as f = (I_O α + ω × I_O ω + h × b,  m b + α × h + ω × (ω × h)), b = a_v + ω × v.
//  - CRBA: for small models in body frames (composite inertia carried to the parent, the force
//    Ic S carried up the chain); for larger ones in the world frame, where every M_ij with j an
//    ancestor of i is a 6-term dot product S_j·(Ic_i S_i) instead of a frame-by-frame transport.
//  - mass_matrix_and_bias fuses the two for small models: one forward sweep (joint transform,
//    RNEA motion and body force) and one backward sweep (RNEA force, CRBA composite and column),
//    each joint transform computed once and loaded once; the per-body steps are shared inline
//    functions (rnea_forward_body, rnea_backward_body, crba_backward_body), not copies.
//  - ABA (forward_dynamics_aba) runs in the world frame, like crba_world: the articulated
//    inertia a body passes to its parent needs no change of frame (a 6×6 add), the body inertias
//    and joint axes are transformed to {0} once; the 6×6 is held as six columns of two 4-lane
//    vectors, so IA·x, the rank-1 update IA − U Uᵀ/D and the add are 12 vector operations each.
//    Faster than CRBA + Cholesky from 2–3 bodies on (bench/README.md, kAbaFrom).
//  - Everything is fixed-size and lives in Data: no allocation.

#if defined(__GNUC__) || defined(__clang__)
#define REFDYN_INLINE inline __attribute__((always_inline))
#else
#define REFDYN_INLINE inline
#endif

// With AVX (the default build uses -march=native) a 4-lane vector is one register and one
// instruction per operation; without it the same code runs on a plain struct of four doubles.
#if (defined(__GNUC__) || defined(__clang__)) && defined(__AVX__)
#define REFDYN_V4_SIMD 1
#endif

namespace refdyn {
namespace {

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

// ---- joints ------------------------------------------------------------------------------------

enum class Kind : unsigned char { RevZ, PrisZ, Rev, Pris };

struct JointKind {
  Kind kind;
  double sign;  ///< +1 or −1 for the ±z kinds
};

REFDYN_INLINE JointKind joint_kind(const Model& m, int i) {
  const Vec3& u = m.axis[i];
  const bool rev = m.joint_type[i] == JointType::Revolute;
  if (u.x() == 0.0 && u.y() == 0.0) return {rev ? Kind::RevZ : Kind::PrisZ, u.z() > 0 ? 1.0 : -1.0};
  return {rev ? Kind::Rev : Kind::Pris, 1.0};
}

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

/// sin, cos of the joint angles q + offset of bodies b .. b+3 (zero past the end).
REFDYN_INLINE void joint_sincos(const Model& m, const double* q, int b, double* s, double* c) {
  v4 x;
  if (b + kBlock <= m.nq) {
    x = ld4(q + b) + ld4(m.offset.data() + b);
  } else {
    x = v4{0.0, 0.0, 0.0, 0.0};
    for (int k = 0; b + k < m.nq; ++k) x[k] = q[b + k] + m.offset[b + k];
  }
  sincos4(x, s, c);
}

/// X = P_i · J_i(q_i) as registers (R columns, p), also stored in X_out. c, s: cos and sin of
/// the joint angle (unused for prismatic joints).
REFDYN_INLINE void joint_transform(const Model& m, int i, const JointKind& k, double qi, double c,
                                   double s, M3& R, v4& p, SE3& X_out) {
  const SE3& P = m.placement[i];
  switch (k.kind) {
    case Kind::RevZ: {
      const M3 PR = ld_rot(P);
      const v4 cv = splat(c), sv = splat(k.sign * s);
      R = {cv * PR.c0 + sv * PR.c1, cv * PR.c1 - sv * PR.c0, PR.c2};
      p = ld3(P.p);
      break;
    }
    case Kind::PrisZ: {
      R = ld_rot(P);
      p = ld3(P.p) + splat(k.sign * (qi + m.offset[i])) * R.c2;
      break;
    }
    case Kind::Rev: {  // Rodrigues: R = P.R (c 1 + s [u]x + (1-c) u uᵀ)
      const Vec3& u = m.axis[i];
      const Mat3 Rj = c * Mat3::Identity() + s * skew(u) + (1 - c) * u * u.transpose();
      const Mat3 PRj = P.R * Rj;
      R = ld(PRj);
      p = ld3(P.p);
      break;
    }
    case Kind::Pris: {
      R = ld_rot(P);
      p = ld3(P.p) + mul(R, ld3(m.axis[i]) * splat(qi + m.offset[i]));
      break;
    }
  }
  st(R, X_out.R);
  st3(p, X_out.p);
}

REFDYN_INLINE void load_transform(const SE3& X, M3& R, v4& p) {
  R = ld_rot(X);
  p = ld3(X.p);
}

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

/// Joint-space component S_iᵀ f of a body-frame force (n, f).
REFDYN_INLINE double project(const Model& m, int i, const JointKind& k, v4 n, v4 f) {
  switch (k.kind) {
    case Kind::RevZ: return k.sign * n[2];
    case Kind::PrisZ: return k.sign * f[2];
    case Kind::Rev: return dot3(ld3(m.axis[i]), n);
    default: return dot3(ld3(m.axis[i]), f);
  }
}

// ---- RNEA --------------------------------------------------------------------------------------

/// Motion of the previous body, carried in registers along a serial chain.
struct MotionCarry {
  v4 w, vv, aw, av;  ///< angular/linear velocity, angular/linear acceleration
};

/// RNEA forward step of body i with its joint transform X = (R, p): body motion from the
/// parent's (registers when the parent is body i−1, else data.v/a), stored in data.v[i],
/// data.a[i], and the body's own force in data.f[i]. a0: base acceleration (−g or 0).
template <bool QD, bool QDD>
REFDYN_INLINE void rnea_forward_body(const Model& model, Data& data, int i, const JointKind& k, const M3& R, v4 p,
                                     const double* qd, const double* qdd, v4 a0, MotionCarry& m) {
  const v4 zero = splat(0.0);
  v4 w = m.w, vv = m.vv, aw = m.aw, av = m.av;
  const M3 Rt = transpose(R);
  const int par = model.parent[i];
  if (par >= 0) {
    if (par != i - 1) {  // tree: the parent's motion from memory
      aw = ld3(data.a[par].w);
      av = ld3(data.a[par].v);
      if constexpr (QD) {
        w = ld3(data.v[par].w);
        vv = ld3(data.v[par].v);
      }
    }
    av = mul(Rt, av - cross(p, aw));
    aw = mul(Rt, aw);
    if constexpr (QD) {
      vv = mul(Rt, vv - cross(p, w));
      w = mul(Rt, w);
    }
  } else {
    aw = zero;
    av = mul(Rt, a0);
    if constexpr (QD) {
      w = zero;
      vv = zero;
    }
  }
  // Joint terms: v += S q̇, a += v ×m S q̇ + S q̈.
  const double dq = QD ? k.sign * qd[i] : 0.0;
  const double ddq = QDD ? k.sign * qdd[i] : 0.0;
  switch (k.kind) {
    case Kind::RevZ:
      if constexpr (QD) {
        const v4 d = splat(dq);
        aw += d * x_cross_ez(w);
        av += d * x_cross_ez(vv);
        w += ez(dq);
      }
      if constexpr (QDD) aw += ez(ddq);
      break;
    case Kind::PrisZ:
      if constexpr (QD) {
        av += splat(dq) * x_cross_ez(w);
        vv += ez(dq);
      }
      if constexpr (QDD) av += ez(ddq);
      break;
    case Kind::Rev: {
      const v4 u = ld3(model.axis[i]);
      if constexpr (QD) {
        const v4 d = splat(dq);
        aw += d * cross(w, u);
        av += d * cross(vv, u);
        w += d * u;
      }
      if constexpr (QDD) aw += splat(ddq) * u;
      break;
    }
    case Kind::Pris: {
      const v4 u = ld3(model.axis[i]);
      if constexpr (QD) {
        const v4 d = splat(dq);
        av += d * cross(w, u);
        vv += d * u;
      }
      if constexpr (QDD) av += splat(ddq) * u;
      break;
    }
  }
  // f = I a + v ×* (I v) = (I_O α + ω × I_O ω + h × b,  m b + α × h + ω × (ω × h)).
  const In I = ld(model.inertia[i]);
  v4 fn, ff;
  if constexpr (QD) {
    const v4 b = av + cross(w, vv);
    const v4 wh = cross(w, I.h);
    fn = mul(I.I, aw) + cross(w, mul(I.I, w)) + cross(I.h, b);
    ff = splat(I.m) * b + cross(aw, I.h) + cross(w, wh);
    st3(w, data.v[i].w);
    st3(vv, data.v[i].v);
  } else {
    fn = mul(I.I, aw) + cross(I.h, av);
    ff = splat(I.m) * av + cross(aw, I.h);
    data.v[i].w.setZero();
    data.v[i].v.setZero();
  }
  st3(aw, data.a[i].w);
  st3(av, data.a[i].v);
  st3(fn, data.f[i].n);
  st3(ff, data.f[i].f);
  m = {w, vv, aw, av};
}

/// The force a child passes to its parent, carried in registers along a serial chain.
struct ForceCarry {
  bool set = false;
  v4 n, f;
};

/// RNEA backward step of body i (X = (R, p) its joint transform): total force = own + the
/// children's, its joint component into out[i], and its share passed on to the parent.
REFDYN_INLINE void rnea_backward_body(const Model& model, Data& data, int i, const M3& R, v4 p, ForceCarry& c,
                                      double* out) {
  v4 fn = ld3(data.f[i].n), ff = ld3(data.f[i].f);
  if (c.set) {
    fn += c.n;
    ff += c.f;
    st3(fn, data.f[i].n);
    st3(ff, data.f[i].f);
  }
  out[i] = project(model, i, joint_kind(model, i), fn, ff);
  const int par = model.parent[i];
  c.set = false;
  if (par >= 0) {
    const v4 tf = mul(R, ff);
    const v4 tn = mul(R, fn) + cross(p, tf);
    if (par == i - 1) {
      c = {true, tn, tf};
    } else {
      st3(ld3(data.f[par].n) + tn, data.f[par].n);
      st3(ld3(data.f[par].f) + tf, data.f[par].f);
    }
  }
}

/// QD: q̇ given (else zero); QDD: q̈ given (else zero). With `have_X` the joint transforms in
/// data.liMi are reused (computed by the caller for the same q).
template <bool QD, bool QDD>
void rnea_impl(const Model& model, Data& data, const double* q, const double* qd, const double* qdd,
               bool gravity, double* out, bool have_X) {
  const int n = model.nq;
  const v4 a0 = gravity ? -ld3(model.gravity) : splat(0.0);
  MotionCarry motion{splat(0.0), splat(0.0), splat(0.0), splat(0.0)};
  double sn[kBlock], cs[kBlock];
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    M3 R;
    v4 p;
    if (have_X) {
      load_transform(data.liMi[i], R, p);
    } else {
      if (i % kBlock == 0) joint_sincos(model, q, i, sn, cs);
      joint_transform(model, i, k, q[i], cs[i % kBlock], sn[i % kBlock], R, p, data.liMi[i]);
    }
    rnea_forward_body<QD, QDD>(model, data, i, k, R, p, qd, qdd, a0, motion);
  }
  // Backward: f_i (total) = own + children's; the child i+1's share is carried in registers.
  ForceCarry force;
  for (int i = n - 1; i >= 0; --i) {
    M3 R;
    v4 p;
    load_transform(data.liMi[i], R, p);
    rnea_backward_body(model, data, i, R, p, force, out);
  }
}

void rnea_dispatch(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
                   const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out, bool have_X) {
  const double* pq = q.data();
  const double* pqd = qd ? qd->data() : nullptr;
  const double* pqdd = qdd ? qdd->data() : nullptr;
  double* o = out.data();
  if (qd && qdd) rnea_impl<true, true>(model, data, pq, pqd, pqdd, gravity, o, have_X);
  else if (qd) rnea_impl<true, false>(model, data, pq, pqd, nullptr, gravity, o, have_X);
  else if (qdd) rnea_impl<false, true>(model, data, pq, nullptr, pqdd, gravity, o, have_X);
  else rnea_impl<false, false>(model, data, pq, nullptr, nullptr, gravity, o, have_X);
}

// ---- CRBA --------------------------------------------------------------------------------------

/// F = I S for the motion subspace S of body i in its own frame.
REFDYN_INLINE void inertia_times_axis(const Model& m, int i, const JointKind& k, const In& I, v4& Fn, v4& Ff,
                                      double& Mii) {
  switch (k.kind) {
    case Kind::RevZ: {  // S = (ez, 0): F = (I ez, ez × h)
      const v4 s = splat(k.sign);
      Fn = s * I.I.c2;
      Ff = -s * x_cross_ez(I.h);
      Mii = I.I.c2[2];
      break;
    }
    case Kind::PrisZ: {  // S = (0, ez): F = (h × ez, m ez)
      const v4 s = splat(k.sign);
      Fn = s * x_cross_ez(I.h);
      Ff = ez(k.sign * I.m);
      Mii = I.m;
      break;
    }
    case Kind::Rev: {
      const v4 u = ld3(m.axis[i]);
      Fn = mul(I.I, u);
      Ff = cross(u, I.h);
      Mii = dot3(u, Fn);
      break;
    }
    case Kind::Pris: {
      const v4 u = ld3(m.axis[i]);
      Fn = cross(I.h, u);
      Ff = splat(I.m) * u;
      Mii = dot3(u, Ff);
      break;
    }
  }
}

/// The composite inertia a child passes to its parent, carried in registers along a chain.
struct InertiaCarry {
  bool set = false;
  In I{};
};

/// Body-frame CRBA backward step of body i (X = (R, p) its joint transform): composite inertia
/// = own (chain) or data.Ic[i] (trees: own + non-adjacent children) + the carried child's;
/// column i of M up the support; the composite passed on to the parent.
REFDYN_INLINE void crba_backward_body(const Model& model, Data& data, int i, bool chain, const M3& R, v4 p,
                                      InertiaCarry& c, double* M, Eigen::Index ld_M) {
  In Ic = ld(chain ? model.inertia[i] : data.Ic[i]);
  if (c.set) add(Ic, c.I);
  st(Ic, data.Ic[i]);
  const JointKind k = joint_kind(model, i);
  v4 Fn, Ff;
  double Mii;
  inertia_times_axis(model, i, k, Ic, Fn, Ff, Mii);
  M[i + ld_M * i] = Mii;
  for (int j = i; model.parent[j] >= 0;) {
    M3 Rj;
    v4 pj;
    if (j == i) {
      Rj = R;
      pj = p;
    } else {
      load_transform(data.liMi[j], Rj, pj);
    }
    Ff = mul(Rj, Ff);
    Fn = mul(Rj, Fn) + cross(pj, Ff);
    j = model.parent[j];
    const double mij = project(model, j, joint_kind(model, j), Fn, Ff);
    M[i + ld_M * j] = mij;
    M[j + ld_M * i] = mij;
  }
  const int par = model.parent[i];
  c.set = false;
  if (par >= 0) {
    const In T = transform(Ic, R, p);
    if (par == i - 1) {
      c = {true, T};
    } else {
      In Ip = ld(data.Ic[par]);
      add(Ip, T);
      st(Ip, data.Ic[par]);
    }
  }
}

/// Joint transforms of all bodies into data.liMi (sin/cos four at a time); true for a serial
/// chain (every parent is the previous body).
REFDYN_INLINE bool all_joint_transforms(const Model& model, Data& data, const double* q) {
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  for (int i = 0; i < model.nq; ++i) {
    M3 R;
    v4 p;
    if (i % kBlock == 0) joint_sincos(model, q, i, sn, cs);
    joint_transform(model, i, joint_kind(model, i), q[i], cs[i % kBlock], sn[i % kBlock], R, p, data.liMi[i]);
    chain &= model.parent[i] == i - 1;
  }
  return chain;
}

/// Trees (body-frame CRBA): the composites of non-adjacent children accumulate in data.Ic, which
/// starts as the bodies' own inertias, and M_ij of bodies on different branches is 0 (never
/// written by the backward sweep).
REFDYN_INLINE void start_tree_composites(const Model& model, Data& data) {
  for (int i = 0; i < model.nq; ++i) data.Ic[i] = model.inertia[i];
  data.M.setZero();
}

/// Body-frame CRBA (Featherstone's): best for small models.
void crba_local(const Model& model, Data& data, const double* q) {
  const int n = model.nq;
  const bool chain = all_joint_transforms(model, data, q);
  if (!chain) start_tree_composites(model, data);
  InertiaCarry c;
  for (int i = n - 1; i >= 0; --i) {
    M3 R;
    v4 p;
    load_transform(data.liMi[i], R, p);
    crba_backward_body(model, data, i, chain, R, p, c, data.M.data(), data.M.rows());
  }
}

/// Body-frame CRBA and RNEA (q̈ = 0, gravity) in one forward and one backward sweep: each
/// joint transform is computed once and loaded once on the way back (small models).
void crba_bias_local(const Model& model, Data& data, const double* q, const double* qd, double* nle) {
  const int n = model.nq;
  const v4 a0 = -ld3(model.gravity);
  MotionCarry motion{splat(0.0), splat(0.0), splat(0.0), splat(0.0)};
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    M3 R;
    v4 p;
    if (i % kBlock == 0) joint_sincos(model, q, i, sn, cs);
    joint_transform(model, i, k, q[i], cs[i % kBlock], sn[i % kBlock], R, p, data.liMi[i]);
    chain &= model.parent[i] == i - 1;
    rnea_forward_body<true, false>(model, data, i, k, R, p, qd, nullptr, a0, motion);
  }
  if (!chain) start_tree_composites(model, data);
  ForceCarry force;
  InertiaCarry inertia;
  for (int i = n - 1; i >= 0; --i) {
    M3 R;
    v4 p;
    load_transform(data.liMi[i], R, p);
    rnea_backward_body(model, data, i, R, p, force, nle);
    crba_backward_body(model, data, i, chain, R, p, inertia, data.M.data(), data.M.rows());
  }
}

/// Joint axis S_i of body i in {0} (angular sw, linear sv about the world origin).
REFDYN_INLINE void world_axis(const Model& m, int i, const JointKind& k, const M3& OR, v4 Op, v4& sw, v4& sv) {
  switch (k.kind) {
    case Kind::RevZ: sw = splat(k.sign) * OR.c2; sv = cross(Op, sw); break;
    case Kind::PrisZ: sw = splat(0.0); sv = splat(k.sign) * OR.c2; break;
    case Kind::Rev: sw = mul(OR, ld3(m.axis[i])); sv = cross(Op, sw); break;
    default: sw = splat(0.0); sv = mul(OR, ld3(m.axis[i])); break;
  }
}

/// Joint transform of body i (sin/cos of four joints at a time into sn, cs when i is a multiple
/// of four) into data.liMi[i], and the body's world pose (OR, Op) from its parent's (carried in
/// registers along a chain, else loaded from data.oMi) into data.oMi[i]. True when the parent is
/// body i − 1 (or the world for body 0 of a chain).
REFDYN_INLINE bool world_pose_step(const Model& model, Data& data, const double* q, int i, const JointKind& k,
                                   double* sn, double* cs, M3& OR, v4& Op) {
  M3 R;
  v4 p;
  if (i % kBlock == 0) joint_sincos(model, q, i, sn, cs);
  joint_transform(model, i, k, q[i], cs[i % kBlock], sn[i % kBlock], R, p, data.liMi[i]);
  const int par = model.parent[i];
  if (par < 0) {
    OR = R;
    Op = p;
  } else {
    if (par != i - 1) load_transform(data.oMi[par], OR, Op);
    Op += mul(OR, p);
    OR = M3{mul(OR, R.c0), mul(OR, R.c1), mul(OR, R.c2)};
  }
  st(OR, data.oMi[i].R);
  st3(Op, data.oMi[i].p);
  return par == i - 1;
}

/// Bodies whose world axes fit the stack buffer of crba_world (6 doubles each).
constexpr int kWorldAxesOnStack = 128;

/// World-frame CRBA: composite inertias and joint axes in {0}, so M_ji = S_j·(Ic_i S_i) for
/// every ancestor j of i; best for larger models. For a serial chain the ancestors of i are
/// 0 .. i-1 and column i above the diagonal is one vectorised pass over the axes stored by
/// component. data.Ic ends holding the composites expressed in {0}, data.oMi the body poses.
void crba_world(const Model& model, Data& data, const double* q) {
  const int n = model.nq;
  // Joint axes in {0}, by component (sw.x, sw.y, sw.z, sv.x, sv.y, sv.z).
  alignas(64) double S[6][kWorldAxesOnStack];
  const bool axes_on_stack = n <= kWorldAxesOnStack;
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  M3 OR{};
  v4 Op{};
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    chain &= world_pose_step(model, data, q, i, k, sn, cs, OR, Op);
    if (axes_on_stack) {
      v4 sw, sv;
      world_axis(model, i, k, OR, Op, sw, sv);
      for (int c = 0; c < 3; ++c) {
        S[c][i] = sw[c];
        S[3 + c][i] = sv[c];
      }
    }
  }
  if (!chain) {  // trees accumulate the composites of non-adjacent children in data.Ic, and
    for (int i = 0; i < n; ++i) data.Ic[i] = Inertia::Zero();
    data.M.setZero();  // M_ij of bodies on different branches is 0 (never written below)
  }
  double* M = data.M.data();
  const Eigen::Index ld_M = data.M.rows();
  bool carry = false;
  In c{};
  for (int i = n - 1; i >= 0; --i) {
    M3 OR_i;
    v4 Op_i;
    load_transform(data.oMi[i], OR_i, Op_i);
    In Ic = transform(ld(model.inertia[i]), OR_i, Op_i);
    if (!chain) add(Ic, ld(data.Ic[i]));
    if (carry) add(Ic, c);
    st(Ic, data.Ic[i]);
    const JointKind k = joint_kind(model, i);
    v4 sw, sv;
    world_axis(model, i, k, OR_i, Op_i, sw, sv);
    // F = Ic S = (I sw + h × sv, m sv − h × sw).
    const v4 Fn = mul(Ic.I, sw) + cross(Ic.h, sv);
    const v4 Ff = splat(Ic.m) * sv + cross(sw, Ic.h);
    double* Mi = M + ld_M * i;  // column i
    Mi[i] = dot3(sw, Fn) + dot3(sv, Ff);
    if (chain && axes_on_stack) {
      const double f0 = Fn[0], f1 = Fn[1], f2 = Fn[2], f3 = Ff[0], f4 = Ff[1], f5 = Ff[2];
      for (int j = 0; j < i; ++j)
        Mi[j] = S[0][j] * f0 + S[1][j] * f1 + S[2][j] * f2 + S[3][j] * f3 + S[4][j] * f4 + S[5][j] * f5;
    } else {
      for (int j = model.parent[i]; j >= 0; j = model.parent[j]) {
        v4 swj, svj;
        if (axes_on_stack) {
          swj = v4{S[0][j], S[1][j], S[2][j], 0.0};
          svj = v4{S[3][j], S[4][j], S[5][j], 0.0};
        } else {
          M3 ORj;
          v4 Opj;
          load_transform(data.oMi[j], ORj, Opj);
          world_axis(model, j, joint_kind(model, j), ORj, Opj, swj, svj);
        }
        Mi[j] = dot3(swj, Fn) + dot3(svj, Ff);
      }
    }
    const int par = model.parent[i];
    carry = false;
    if (par == i - 1) {
      c = Ic;
      carry = true;
    } else if (par >= 0) {
      In Ip = ld(data.Ic[par]);
      add(Ip, Ic);
      st(Ip, data.Ic[par]);
    }
  }
  // Lower triangle from the upper one (rows of a column-major matrix are strided).
  for (int i = 0; i < n; ++i) {
    const double* Mi = M + ld_M * i;
    if (chain) {
      for (int j = 0; j < i; ++j) M[i + ld_M * j] = Mi[j];
    } else {
      for (int j = model.parent[i]; j >= 0; j = model.parent[j]) M[i + ld_M * j] = Mi[j];
    }
  }
}

/// Below this many bodies the body-frame CRBA is faster (measured crossover: 6–7 bodies).
constexpr int kWorldCrbaFrom = 7;

void crba_impl(const Model& model, Data& data, const Eigen::VectorXd& q) {
  if (model.nq < kWorldCrbaFrom) crba_local(model, data, q.data());
  else crba_world(model, data, q.data());
}

// ---- ABA ---------------------------------------------------------------------------------------

/// A spatial vector (angular, linear part) in registers.
struct SV {
  v4 w, v;
};
REFDYN_INLINE SV ld(const double (&x)[2][4]) { return {ld4(x[0]), ld4(x[1])}; }
REFDYN_INLINE void st(const SV& a, double (&x)[2][4]) {
  st4(a.w, x[0]);
  st4(a.v, x[1]);
}
REFDYN_INLINE double dot6(const SV& a, const SV& b) { return dot3(a.w, b.w) + dot3(a.v, b.v); }

/// A symmetric 6×6 (articulated) inertia as six columns: column k is the image of the unit
/// motion e_k (k < 3: angular, else linear).
struct M6 {
  SV c[6];
};
REFDYN_INLINE SV mul(const M6& A, const SV& x) {
  SV o{A.c[0].w * bc<0>(x.w), A.c[0].v * bc<0>(x.w)};
  o.w += A.c[1].w * bc<1>(x.w) + A.c[2].w * bc<2>(x.w);
  o.v += A.c[1].v * bc<1>(x.w) + A.c[2].v * bc<2>(x.w);
  o.w += A.c[3].w * bc<0>(x.v) + A.c[4].w * bc<1>(x.v) + A.c[5].w * bc<2>(x.v);
  o.v += A.c[3].v * bc<0>(x.v) + A.c[4].v * bc<1>(x.v) + A.c[5].v * bc<2>(x.v);
  return o;
}
REFDYN_INLINE void add(M6& A, const M6& B) {
  for (int k = 0; k < 6; ++k) {
    A.c[k].w += B.c[k].w;
    A.c[k].v += B.c[k].v;
  }
}
/// A rigid-body inertia (m, h, I) as a 6×6: columns (I e_k, e_k × h) and (h × e_k, m e_k).
REFDYN_INLINE M6 six(const In& I) {
  const v4 ex{1.0, 0.0, 0.0, 0.0}, ey{0.0, 1.0, 0.0, 0.0}, ez1{0.0, 0.0, 1.0, 0.0};
  const v4 xh = cross(ex, I.h), yh = cross(ey, I.h), zh = cross(ez1, I.h);
  const v4 m = splat(I.m);
  return {{{I.I.c0, xh}, {I.I.c1, yh}, {I.I.c2, zh}, {-xh, m * ex}, {-yh, m * ey}, {-zh, m * ez1}}};
}
REFDYN_INLINE M6 ld(const double (&x)[6][2][4]) {
  M6 A;
  for (int k = 0; k < 6; ++k) A.c[k] = {ld4(x[k][0]), ld4(x[k][1])};
  return A;
}
REFDYN_INLINE void st(const M6& A, double (&x)[6][2][4]) {
  for (int k = 0; k < 6; ++k) {
    st4(A.c[k].w, x[k][0]);
    st4(A.c[k].v, x[k][1]);
  }
}

/// ABA's last sweep, shared by aba_world and aba_solve_impl: x holds u_i on entry and q̈_i on
/// return, x_i = (u_i − U_iᵀ a'_i) / D_i, a'_i = a_parent (+ c_i with Bias), a_i = a'_i + S_i x_i,
/// a = a0 at the roots; the parent's a from registers along a chain, from data.aba in trees.
template <bool Bias>
REFDYN_INLINE void aba_forward_sweep(const Model& model, AbaBody* __restrict B, bool chain, const SV& a0, double* x) {
  SV acc = a0;
  for (int i = 0; i < model.nq; ++i) {
    const int par = model.parent[i];
    if (par < 0) acc = a0;
    else if (par != i - 1) acc = ld(B[par].a);
    if constexpr (Bias) {
      const SV c = ld(B[i].c);
      acc.w += c.w;
      acc.v += c.v;
    }
    const double xi = (x[i] - dot6(ld(B[i].U), acc)) * B[i].Dinv;
    x[i] = xi;
    const SV S = ld(B[i].S);
    const v4 sx = splat(xi);
    acc.w += S.w * sx;
    acc.v += S.v * sx;
    if (!chain) st(acc, B[i].a);
  }
}

/// Featherstone's articulated-body algorithm in the world frame {0} (spatial vectors at the
/// world origin; as Pinocchio does it, so that the articulated inertia a body passes to its
/// parent needs no change of frame: Ia_parent += IA − U Uᵀ/D). Three sweeps:
///  1. forward: joint and world transforms, joint axis S_i in {0}, velocity v_i = v_par + S_i q̇_i,
///     velocity-product acceleration c_i = v_i ×m S_i q̇_i, body inertia I_i in {0} and bias
///     force p_i = v_i ×* I_i v_i;
///  2. backward: U_i = IA_i S_i, D_i = S_iᵀ U_i, u_i = τ_i − S_iᵀ p_i; the parent receives
///     Ia = IA_i − U_i U_iᵀ / D_i and pa = p_i + Ia c_i + U_i u_i / D_i;
///  3. forward: a'_i = a_par + c_i, q̈_i = (u_i − U_iᵀ a'_i) / D_i, a_i = a'_i + S_i q̈_i, with
///     a_base = −g (gravity as a base acceleration).
/// Serial chains carry the parent's or child's quantities in registers; trees accumulate the
/// children's contributions in data.aba. Returns the first body whose D_i is not positive
/// (the mass matrix is then not positive definite), or −1.
int aba_world(const Model& model, Data& data, const double* q, const double* qd, const double* tau, double* qdd) {
  const int n = model.nq;
  AbaBody* __restrict B = data.aba.data();
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  M3 OR{};
  v4 Op{};
  SV vel{splat(0.0), splat(0.0)};
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    const int par = model.parent[i];
    if (par < 0) vel = {splat(0.0), splat(0.0)};
    else if (par != i - 1) vel = ld(B[par].v);  // tree: the parent's velocity from memory
    chain &= world_pose_step(model, data, q, i, k, sn, cs, OR, Op);
    SV S;
    world_axis(model, i, k, OR, Op, S.w, S.v);
    const v4 d = splat(qd[i]);
    const SV sq{S.w * d, S.v * d};
    vel.w += sq.w;
    vel.v += sq.v;
    const SV c{cross(vel.w, sq.w), cross(vel.w, sq.v) + cross(vel.v, sq.w)};
    const In I = transform(ld(model.inertia[i]), OR, Op);
    st(I, data.Ic[i]);
    // p = v ×* (I v), I v = (I ω + h × v, m v − h × ω).
    const v4 hn = mul(I.I, vel.w) + cross(I.h, vel.v);
    const v4 hf = splat(I.m) * vel.v - cross(I.h, vel.w);
    const SV pb{cross(vel.w, hn) + cross(vel.v, hf), cross(vel.w, hf)};
    st(S, B[i].S);
    st(c, B[i].c);
    st(pb, B[i].p);
    st(vel, B[i].v);
  }
  if (!chain)
    for (int i = 0; i < n; ++i) std::memset(B[i].Ia, 0, sizeof B[i].Ia);
  // Backward: the child's contribution (Ia, pa) is carried in registers along a chain.
  M6 Ia{};
  SV pa{splat(0.0), splat(0.0)};
  bool carry = false;
  for (int i = n - 1; i >= 0; --i) {
    M6 IA = six(ld(data.Ic[i]));
    SV pA = ld(B[i].p);
    if (!chain) add(IA, ld(B[i].Ia));
    if (carry) {
      add(IA, Ia);
      pA.w += pa.w;
      pA.v += pa.v;
    }
    const SV S = ld(B[i].S);
    const SV U = mul(IA, S);
    const double D = dot6(S, U);
    const double Dinv = 1.0 / D;
    B[i].Dinv = Dinv;
    if (!(D > 0)) return i;
    const double u = tau[i] - dot6(S, pA);
    st(U, B[i].U);
    qdd[i] = u;  // the last sweep turns it into q̈_i
    const int par = model.parent[i];
    carry = false;
    if (par < 0) continue;
    // Ia = IA − U Uᵀ/D, column k: IA e_k − U (U_k/D).
    const v4 Ud_w = U.w * splat(Dinv), Ud_v = U.v * splat(Dinv);
    const double Uk[6] = {Ud_w[0], Ud_w[1], Ud_w[2], Ud_v[0], Ud_v[1], Ud_v[2]};
    for (int kk = 0; kk < 6; ++kk) {
      const v4 s = splat(Uk[kk]);
      IA.c[kk].w -= U.w * s;
      IA.c[kk].v -= U.v * s;
    }
    const SV Iac = mul(IA, ld(B[i].c));
    const v4 su = splat(u * Dinv);
    pA.w += Iac.w + U.w * su;
    pA.v += Iac.v + U.v * su;
    if (par == i - 1) {
      Ia = IA;
      pa = pA;
      carry = true;
    } else {
      M6 Ip = ld(B[par].Ia);
      add(Ip, IA);
      st(Ip, B[par].Ia);
      st(SV{ld4(B[par].p[0]) + pA.w, ld4(B[par].p[1]) + pA.v}, B[par].p);
    }
  }
  // Forward: accelerations (gravity as the base acceleration −g).
  aba_forward_sweep<true>(model, B, chain, SV{splat(0.0), -ld3(model.gravity)}, qdd);
  return -1;
}

/// x = M⁻¹ τ with the articulated-body factorization the last aba_world call left in data.aba
/// (U_i, D_i, S_i at that q): ABA's backward and forward sweeps without velocity and gravity
/// terms, O(n). data.aba's p and a are its scratch (trees).
void aba_solve_impl(const Model& model, Data& data, const double* tau, double* x) {
  const int n = model.nq;
  AbaBody* __restrict B = data.aba.data();
  bool chain = true;
  for (int i = 0; i < n; ++i) chain &= model.parent[i] == i - 1;
  const SV zero{splat(0.0), splat(0.0)};
  if (!chain)
    for (int i = 0; i < n; ++i) st(zero, B[i].p);
  SV carry = zero;
  for (int i = n - 1; i >= 0; --i) {
    SV pA = carry;  // the child i + 1's share (registers), plus in a tree the others' (memory)
    if (!chain) {
      pA.w += ld4(B[i].p[0]);
      pA.v += ld4(B[i].p[1]);
    }
    const double u = tau[i] - dot6(ld(B[i].S), pA);
    x[i] = u;
    const int par = model.parent[i];
    carry = zero;
    if (par < 0) continue;
    const SV U = ld(B[i].U);
    const v4 s = splat(u * B[i].Dinv);
    pA.w += U.w * s;
    pA.v += U.v * s;
    if (par == i - 1) carry = pA;
    else st(SV{ld4(B[par].p[0]) + pA.w, ld4(B[par].p[1]) + pA.v}, B[par].p);
  }
  aba_forward_sweep<false>(model, B, chain, zero, x);
}

/// Argument checks with a fast success path; on failure the library's checks produce the
/// error message (and throw).
REFDYN_INLINE bool fine(const Eigen::VectorXd& x, int n) { return x.size() == n && x.allFinite(); }
REFDYN_INLINE void check_q_fast(const Model& model, const Eigen::VectorXd& q) {
  if (!fine(q, model.nq)) model.check_q(q);
}
REFDYN_INLINE void check_vector_fast(const char* what, const Eigen::VectorXd& x, int n) {
  if (!fine(x, n)) check_vector(what, x, n);
}

}  // namespace

namespace unchecked {

void rnea(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
          const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out) {
  rnea_dispatch(model, data, q, qd, qdd, gravity, out, false);
}

void crba(const Model& model, Data& data, const Eigen::VectorXd& q) { crba_impl(model, data, q); }

void rnea_reusing_placements(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
                             const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out) {
  rnea_dispatch(model, data, q, qd, qdd, gravity, out, true);
}

namespace {
template <int N>
bool solve_fixed(const Eigen::MatrixXd& M, Eigen::VectorXd& b) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(Eigen::Map<const Eigen::Matrix<double, N, N>>(M.data()));
  if (llt.info() != Eigen::Success) return false;
  Eigen::Map<Eigen::Matrix<double, N, 1>> x(b.data());
  llt.solveInPlace(x);
  return true;
}
}  // namespace

int aba(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
        const Eigen::VectorXd& tau, Eigen::VectorXd& qdd) {
  return aba_world(model, data, q.data(), qd.data(), tau.data(), qdd.data());
}

void aba_solve(const Model& model, Data& data, const double* tau, double* x) { aba_solve_impl(model, data, tau, x); }

bool solve_mass_matrix(Data& data, Eigen::VectorXd& b) {
  switch (data.M.rows()) {  // fixed-size Cholesky on the stack for small models
    case 1: return solve_fixed<1>(data.M, b);
    case 2: return solve_fixed<2>(data.M, b);
    case 3: return solve_fixed<3>(data.M, b);
    case 4: return solve_fixed<4>(data.M, b);
    default:
      data.llt.compute(data.M);
      if (data.llt.info() != Eigen::Success) return false;
      data.llt.solveInPlace(b);
      return true;
  }
}

void mass_matrix_and_bias(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  if (model.nq < kWorldCrbaFrom) {
    crba_bias_local(model, data, q.data(), qd.data(), data.nle.data());
  } else {
    crba_world(model, data, q.data());
    rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), true);
  }
}

}  // namespace unchecked

const Eigen::VectorXd& inverse_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  check_vector_fast("qdd", qdd, model.nv);
  rnea_impl<true, true>(model, data, q.data(), qd.data(), qdd.data(), true, data.tau.data(), false);
  return data.tau;
}

const Eigen::VectorXd& bias_forces(const Model& model, Data& data, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qd) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), false);
  return data.nle;
}

const Eigen::VectorXd& gravity_forces(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  check_q_fast(model, q);
  rnea_impl<false, false>(model, data, q.data(), nullptr, nullptr, true, data.g.data(), false);
  return data.g;
}

const Eigen::MatrixXd& mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  check_q_fast(model, q);
  crba_impl(model, data, q);
  return data.M;
}

namespace {
void check_forward_dynamics_arguments(const Model& model, const Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  check_vector_fast("tau", tau, model.nv);
}
}  // namespace

const Eigen::VectorXd& forward_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  return forward_dynamics_uses_aba(model.nq) ? forward_dynamics_aba(model, data, q, qd, tau)
                                             : forward_dynamics_crba(model, data, q, qd, tau);
}

const Eigen::VectorXd& forward_dynamics_aba(const Model& model, Data& data, const Eigen::VectorXd& q,
                                            const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  check_forward_dynamics_arguments(model, data, q, qd, tau);
  const int body = aba_world(model, data, q.data(), qd.data(), tau.data(), data.ddq.data());
  if (body >= 0)
    throw Error("forward_dynamics: the mass matrix is not positive definite at this q: the articulated inertia "
                "about joint '" + model.joint_name[body] + "' is " + fmt(1.0 / data.aba[body].Dinv) +
                " (hint: a massless link at the end of a chain, or a joint that moves no mass)");
  return data.ddq;
}

const Eigen::VectorXd& forward_dynamics_crba(const Model& model, Data& data, const Eigen::VectorXd& q,
                                             const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  check_forward_dynamics_arguments(model, data, q, qd, tau);
  crba_impl(model, data, q);
  // The joint transforms in data.liMi are those of this q: reuse them.
  rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), true);
  data.ddq = tau - data.nle;
  if (!unchecked::solve_mass_matrix(data, data.ddq))
    throw Error("forward_dynamics: the mass matrix is not positive definite at this q "
                "(hint: a massless link at the end of a chain, or a joint that moves no mass)");
  return data.ddq;
}

double kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  check_data(model, data);
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  double T = 0;
  for (int i = 0; i < model.nq; ++i) {
    const SE3& X = data.liMi[i] = joint_placement(model, i, q[i]);
    const int p = model.parent[i];
    data.v[i] = (p < 0 ? Motion::Zero() : X.act_inv(data.v[p])) + model.motion_subspace(i) * qd[i];
    T += 0.5 * dot(data.v[i], model.inertia[i] * data.v[i]);
  }
  return T;
}

double potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  forward_kinematics(model, data, q);
  double V = 0;
  for (int i = 0; i < model.nq; ++i) {
    const Inertia& I = model.inertia[i];
    const Vec3 mc_world = data.oMi[i].R * I.h + I.m * data.oMi[i].p;
    V -= model.gravity.dot(mc_world);
  }
  return V;
}

}  // namespace refdyn
