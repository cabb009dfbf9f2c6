#pragma once
/// Forward kinematics over a scalar S (double, Dual<N>, GiNaC::ex): body poses, body velocities
/// and accelerations in body axes, and the world position, velocity, acceleration and Jacobian
/// columns of a point. Conventions of docs/notation.md (body i's frame is its joint frame after
/// the joint motion; velocities are those of the frame origin).
///
///   joint:        X_i = P_i · J_i(q_i + offset_i)                          (local_R, local_p)
///   pose:         ⁰X_i = ⁰X_parent · X_i                                   (R, p)
///   velocity:     ω_i = Eᵢ ω_p + u_i q̇_i (revolute),  v_i = Eᵢ (v_p + ω_p × p_i) + u_i q̇_i (prismatic)
///   acceleration: ω̇_i = Eᵢ ω̇_p + u_i q̈_i + (Eᵢ ω_p) × u_i q̇_i                 (revolute)
///                 a_i = Eᵢ (a_p + ω̇_p × p_i + ω_p × (ω_p × p_i))
///                       [+ 2 (Eᵢ ω_p) × u_i q̇_i + u_i q̈_i                     (prismatic)]
/// with Eᵢ = local_Rᵢᵀ (parent axes → body axes), p_i = local_p_i, u_i the body-frame axis, and
/// the base accelerating with a_base (−g for inverse dynamics, 0 for kinematics).
#include "refdyn/multibody/body.hpp"

#include <vector>

namespace refdyn::multibody {

/// X_i = P_i · J_i(x), x = q_i + offset_i: rotation by x about u (Rodrigues,
/// c 1 + s [u]× + (1 − c) u uᵀ) or translation by x u.
template <class S>
void joint_transform(const Body<S>& B, const S& qi, Mat3T<S>& R, Vec3T<S>& p) {
  const S x = qi + B.offset;
  const Vec3T<S>& a = B.axis;
  if (B.type == JointType::Revolute) {
    const S c = cos_of(x), sn = sin_of(x), one_c = from_double<S>(1.0) - c;
    const Mat3T<S> K = skew(a);
    Mat3T<S> J;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) {
        // terms with a structurally zero axis factor are skipped (the DH axis z has 6 of 9 in
        // [u]× and 8 of 9 in u uᵀ): fewer dual products, fewer GiNaC temporaries
        S e = r == k ? c : from_double<S>(0.0);
        if (!is_zero(K[3 * r + k])) e = e + sn * K[3 * r + k];
        const S uu = a[r] * a[k];
        if (!is_zero(uu)) e = e + one_c * uu;
        J[3 * r + k] = e;
      }
    R = mul(B.R, J);
    p = B.p;
  } else {
    R = B.R;
    p = add(B.p, mul(B.R, scale(a, x)));
  }
}

/// Body poses: local (in the parent's frame; the world's for roots) and world.
template <class S>
struct Poses {
  std::vector<Mat3T<S>> local_R, R;
  std::vector<Vec3T<S>> local_p, p;
};

/// ⁰X_i = ⁰X_parent · X_i for every body (roots: ⁰X_i = X_i).
template <class S>
void forward_poses(const Bodies<S>& bodies, const std::vector<S>& q, Poses<S>& out) {
  const int n = bodies.size();
  out.local_R.resize(n);
  out.local_p.resize(n);
  out.R.resize(n);
  out.p.resize(n);
  for (int i = 0; i < n; ++i) {
    const Body<S>& B = bodies.bodies[i];
    joint_transform(B, q[i], out.local_R[i], out.local_p[i]);
    if (B.parent < 0) {
      out.R[i] = out.local_R[i];
      out.p[i] = out.local_p[i];
    } else {
      out.R[i] = mul(out.R[B.parent], out.local_R[i]);
      out.p[i] = add(out.p[B.parent], mul(out.R[B.parent], out.local_p[i]));
    }
  }
}
template <class S>
Poses<S> forward_poses(const Bodies<S>& bodies, const std::vector<S>& q) {
  Poses<S> out;
  forward_poses(bodies, q, out);
  return out;
}

/// Body motion in body axes: angular velocity ω, angular acceleration ω̇, velocity v and
/// acceleration a of the body origin (v only when asked for).
template <class S>
struct Motions {
  std::vector<Vec3T<S>> w, wd, v, a;
};

/// The velocity and acceleration recursion above. qd, qdd: n values each, or nullptr for zero
/// (the terms are then skipped, not multiplied by 0). a_base: the base acceleration in world
/// axes. velocities: also fill v.
template <class S>
void forward_motion(const Bodies<S>& bodies, const Poses<S>& poses, const S* qd, const S* qdd, const Vec3T<S>& a_base,
                    bool velocities, Motions<S>& m) {
  const int n = bodies.size();
  m.w.resize(n);
  m.wd.resize(n);
  m.a.resize(n);
  m.v.resize(velocities ? n : 0);
  const Vec3T<S> zero = zero3<S>();
  for (int i = 0; i < n; ++i) {
    const Body<S>& B = bodies.bodies[i];
    const int par = B.parent;
    const Mat3T<S> E = transpose(poses.local_R[i]);  // parent → body
    const Vec3T<S>& pl = poses.local_p[i];
    const Vec3T<S>& w_p = par < 0 ? zero : m.w[par];
    const Vec3T<S>& wd_p = par < 0 ? zero : m.wd[par];
    const Vec3T<S>& a_p = par < 0 ? a_base : m.a[par];
    const Vec3T<S>& ax = B.axis;
    const Vec3T<S> w_in = mul(E, w_p);  // the parent's angular velocity in body axes
    m.a[i] = mul(E, add(add(a_p, cross(wd_p, pl)), cross(w_p, cross(w_p, pl))));
    if (velocities) {
      const Vec3T<S>& v_p = par < 0 ? zero : m.v[par];
      m.v[i] = mul(E, add(v_p, cross(w_p, pl)));
      if (B.type != JointType::Revolute && qd) m.v[i] = add(m.v[i], scale(ax, qd[i]));
    }
    if (B.type == JointType::Revolute) {
      m.w[i] = qd ? add(w_in, scale(ax, qd[i])) : w_in;
      m.wd[i] = mul(E, wd_p);
      if (qdd) m.wd[i] = add(m.wd[i], scale(ax, qdd[i]));
      if (qd) m.wd[i] = add(m.wd[i], cross(w_in, scale(ax, qd[i])));
    } else {
      m.w[i] = w_in;
      m.wd[i] = mul(E, wd_p);
      if (qd) m.a[i] = add(m.a[i], scale(cross(w_in, ax), from_double<S>(2.0) * qd[i]));
      if (qdd) m.a[i] = add(m.a[i], scale(ax, qdd[i]));
    }
  }
}

/// World position r, velocity ṙ and acceleration r̈ of a point fixed on a body (body −1: fixed
/// in the world): with d = ⁰R_b r_b,  r = ⁰p_b + d,  ṙ = ⁰R_b (v_b + ω_b × r_b),
/// r̈ = ⁰R_b (a_b + ω̇_b × r_b + ω_b × (ω_b × r_b)). motion may be nullptr (position only); its
/// v must be filled for ṙ.
template <class S>
struct PointKinematics {
  Vec3T<S> r, v, a;
};
template <class S>
Vec3T<S> point_position(const Point<S>& P, const Poses<S>& poses) {
  if (P.body < 0) return P.position;
  return add(poses.p[P.body], mul(poses.R[P.body], P.position));
}
template <class S>
PointKinematics<S> point_kinematics(const Point<S>& P, const Poses<S>& poses, const Motions<S>& m) {
  PointKinematics<S> k;
  k.r = point_position(P, poses);
  if (P.body < 0) {
    k.v = k.a = zero3<S>();
    return k;
  }
  const int b = P.body;
  const Vec3T<S>& rb = P.position;
  const Mat3T<S>& R = poses.R[b];
  k.v = mul(R, add(m.v[b], cross(m.w[b], rb)));
  k.a = mul(R, add(add(m.a[b], cross(m.wd[b], rb)), cross(m.w[b], cross(m.w[b], rb))));
  return k;
}

/// Column j of the point Jacobian C = ∂r/∂q (world axes) for a point at world position r on a
/// body that joint j supports: z_j × (r − ⁰p_j) (revolute) or z_j (prismatic), z_j = ⁰R_j u_j.
template <class S>
Vec3T<S> point_jacobian_column(const Bodies<S>& bodies, const Poses<S>& poses, int j, const Vec3T<S>& r) {
  const Vec3T<S> z = mul(poses.R[j], bodies.bodies[j].axis);
  return bodies.bodies[j].type == JointType::Revolute ? cross(z, sub(r, poses.p[j])) : z;
}

}  // namespace refdyn::multibody
