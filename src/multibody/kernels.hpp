#pragma once
// Private to the fast double kernels: the per-body steps shared by RNEA (rnea.cpp), CRBA and the
// fused M, c + g sweep (crba.cpp) and ABA (aba.cpp), and the RNEA kernel itself (also used by
// crba.cpp). Not installed. The helpers are force-inlined (REFDYN_INLINE) so that the compiler
// inlines them across the three files as it did when they were one file.
#include "kernels_v4.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

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
//  Files: kernels_v4.hpp (4-lane algebra), this header (joints, per-body steps, rnea_impl),
//  rnea.cpp, crba.cpp (CRBA, fused M + bias, FD by CRBA + Cholesky), aba.cpp (ABA, M⁻¹ solves),
//  recursive_dynamics.cpp (forward_dynamics' choice, energies).

namespace refdyn::kernels {

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

/// sin, cos of the joint angles q + offset of bodies b .. b+3 (zero past the end).
REFDYN_INLINE void joint_sincos(const Model& m, const double* q, int b, double* s, double* c) {
  v4 x;
  if (b + kBlock <= m.nq) {
    x = ld4(q + b) + ld4(m.offset.data() + b);
  } else {
    // The last 1–3 angles, lanes past the end zero, built in registers with fixed lanes. Writing
    // x[k] for a variable k goes through the stack, and the vector load after those scalar
    // stores cannot be forwarded from them: a stall on every call when nq is not a multiple of 4.
    const int r = m.nq - b;
    const double* a = q + b;
    const double* o = m.offset.data() + b;
    x = v4{a[0] + o[0], r > 1 ? a[1] + o[1] : 0.0, r > 2 ? a[2] + o[2] : 0.0, 0.0};
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

// ---- armature ----------------------------------------------------------------------------------

/// M_ii += a_i (Model::armature; joints without armature are left untouched, bit for bit).
REFDYN_INLINE void add_armature(const Model& model, double* M, Eigen::Index ld_M) {
  for (int i = 0; i < model.nq; ++i)
    if (model.armature[i] != 0.0) M[i + ld_M * i] += model.armature[i];
}
/// τ_i += a_i q̈_i (the same joints).
REFDYN_INLINE void add_armature_torque(const Model& model, const double* qdd, double* tau) {
  for (int i = 0; i < model.nq; ++i)
    if (model.armature[i] != 0.0) tau[i] += model.armature[i] * qdd[i];
}

/// QD: q̇ given (else zero); QDD: q̈ given (else zero). With `have_X` the joint transforms in
/// data.liMi are reused (computed by the caller for the same q). Internal linkage (static), as
/// when it was local to one file: each of rnea.cpp and crba.cpp has its own copy, which the
/// compiler may specialise for its callers.
template <bool QD, bool QDD>
static void rnea_impl(const Model& model, Data& data, const double* q, const double* qd, const double* qdd,
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
  if constexpr (QDD) add_armature_torque(model, qdd, out);
}

// ---- CRBA steps (shared by crba.cpp's sweeps) --------------------------------------------------

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

// ---- world frame (crba_world and ABA) ----------------------------------------------------------

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

// ---- argument checks ---------------------------------------------------------------------------

/// Argument checks with a fast success path; on failure the library's checks produce the
/// error message (and throw).
REFDYN_INLINE bool fine(const Eigen::VectorXd& x, int n) { return x.size() == n && x.allFinite(); }
REFDYN_INLINE void check_q_fast(const Model& model, const Eigen::VectorXd& q) {
  if (!fine(q, model.nq)) model.check_q(q);
}
REFDYN_INLINE void check_vector_fast(const char* what, const Eigen::VectorXd& x, int n) {
  if (!fine(x, n)) check_vector(what, x, n);
}
/// The checks of forward_dynamics_aba and forward_dynamics_crba (recursive_dynamics.cpp).
void check_forward_dynamics_arguments(const Model& model, const Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd, const Eigen::VectorXd& tau);

}  // namespace refdyn::kernels
