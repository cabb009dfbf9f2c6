// The articulated-body algorithm (world frame) and the O(n) M⁻¹ solves with its factorization
// (the fast double kernels; see kernels.hpp).
#include "refdyn/multibody/recursive_dynamics.hpp"

#include "kernels.hpp"
#include "refdyn/common/text.hpp"

namespace refdyn {
namespace kernels {
namespace {

// The overloads below for spatial vectors and 6×6 matrices join those of kernels_v4.hpp.
using kernels::add;
using kernels::ld;
using kernels::mul;
using kernels::st;

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
///  2. backward: U_i = IA_i S_i, D_i = S_iᵀ U_i + a_i (a_i the joint's armature), u_i = τ_i − S_iᵀ p_i; the parent receives
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
    double D = dot6(S, U);
    if (model.armature[i] != 0.0) D += model.armature[i];  // D_i = S_iᵀ IA_i S_i + a_i
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

}  // namespace
}  // namespace kernels

using kernels::aba_solve_impl;
using kernels::aba_world;
using kernels::check_forward_dynamics_arguments;

namespace unchecked {

int aba(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
        const Eigen::VectorXd& tau, Eigen::VectorXd& qdd) {
  return aba_world(model, data, q.data(), qd.data(), tau.data(), qdd.data());
}

void aba_solve(const Model& model, Data& data, const double* tau, double* x) { aba_solve_impl(model, data, tau, x); }

}  // namespace unchecked

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

}  // namespace refdyn
