#pragma once
/// Recursive Newton–Euler inverse dynamics over a scalar S (double, Dual<N>, GiNaC::ex):
///
///     τ = M(q) q̈ + c(q, q̇) + g(q)        (docs/notation.md; g = ∂V/∂q, gravity as a base
///                                          acceleration −g)
///
/// With every body quantity in the body's own axes (the joint axis is a constant there, and one
/// joint rotation separates a body from its parent, which keeps symbolic formulas short; a
/// prismatic joint's M_ii is the sliding mass itself), the body motion of generic_kinematics.hpp
/// and the inertia (m, h = m c, I about the origin O):
///     f_i = m a_i + ω̇_i × h + ω_i × (ω_i × h),   n_i = I ω̇_i + ω_i × I ω_i + h × a_i
///     τ_i = u_iᵀ n_i (revolute) or u_iᵀ f_i (prismatic)
///     f_p += X_i f_i,  n_p += X_i n_i + p_i × (X_i f_i)      (X_i = local_R_i, leaves to root)
/// The fast double kernels (recursive_dynamics.hpp) compute the same τ with spatial algebra;
/// tests/generic_dynamics_test.cpp checks the two against each other.
#include "refdyn/multibody/generic_kinematics.hpp"

#include <vector>

namespace refdyn::multibody {

/// Scratch of inverse_dynamics, reusable across calls (no allocation once sized).
template <class S>
struct NewtonEulerWork {
  Motions<S> motion;
  std::vector<Vec3T<S>> f, n;  ///< body forces and moments about the origin, body axes
};

/// τ from body motions already computed (forward_motion with the base acceleration −g or 0).
template <class S>
void newton_euler_backward(const Bodies<S>& bodies, const Poses<S>& poses, const Motions<S>& mo,
                           std::vector<Vec3T<S>>& f, std::vector<Vec3T<S>>& nn, std::vector<S>& tau) {
  const int n = bodies.size();
  f.resize(n);
  nn.resize(n);
  tau.resize(n);
  for (int i = 0; i < n; ++i) {
    const Body<S>& B = bodies.bodies[i];
    const Vec3T<S>& w = mo.w[i];
    const Vec3T<S>& wd = mo.wd[i];
    const Vec3T<S>& a = mo.a[i];
    f[i] = add(add(scale(a, B.m), cross(wd, B.h)), cross(w, cross(w, B.h)));
    nn[i] = add(add(mul(B.I, wd), cross(w, mul(B.I, w))), cross(B.h, a));
  }
  for (int i = n; i-- > 0;) {
    const Body<S>& B = bodies.bodies[i];
    tau[i] = B.type == JointType::Revolute ? dot(B.axis, nn[i]) : dot(B.axis, f[i]);
    if (B.parent >= 0) {
      const Vec3T<S> fp = mul(poses.local_R[i], f[i]);
      f[B.parent] = add(f[B.parent], fp);
      nn[B.parent] = add(add(nn[B.parent], mul(poses.local_R[i], nn[i])), cross(poses.local_p[i], fp));
    }
  }
}

/// τ = M q̈ + c + g (gravity true) or M q̈ + c (false) at the poses' q → tau, M including the
/// joints' armature (Body::armature). qd, qdd: n values each, or nullptr for zero.
template <class S>
void inverse_dynamics(const Bodies<S>& bodies, const Poses<S>& poses, const Vec3& gravity, const S* qd, const S* qdd,
                      bool with_gravity, NewtonEulerWork<S>& work, std::vector<S>& tau) {
  const Vec3T<S> a_base = with_gravity ? scale(lift<S>(gravity), from_double<S>(-1.0)) : zero3<S>();
  forward_motion(bodies, poses, qd, qdd, a_base, false, work.motion);
  newton_euler_backward(bodies, poses, work.motion, work.f, work.n, tau);
  if (qdd)  // the joints' armature: τ_i += a_i q̈_i
    for (int i = 0; i < bodies.size(); ++i)
      if (!is_zero(bodies.bodies[i].armature)) tau[i] = tau[i] + bodies.bodies[i].armature * qdd[i];
}
/// The same, returning τ (allocates its scratch).
template <class S>
std::vector<S> inverse_dynamics(const Bodies<S>& bodies, const Poses<S>& poses, const Vec3& gravity, const S* qd,
                                const S* qdd, bool with_gravity) {
  NewtonEulerWork<S> work;
  std::vector<S> tau;
  inverse_dynamics(bodies, poses, gravity, qd, qdd, with_gravity, work, tau);
  return tau;
}

/// M(q), row-major n×n, column j = inverse_dynamics with q̈ = e_j, q̇ = 0, no gravity (the lower
/// triangle computed, the upper mirrored).
template <class S>
std::vector<S> mass_matrix(const Bodies<S>& bodies, const Poses<S>& poses) {
  const int n = bodies.size();
  std::vector<S> M(static_cast<std::size_t>(n) * n, from_double<S>(0.0));
  std::vector<S> e(n, from_double<S>(0.0)), col;
  NewtonEulerWork<S> work;
  for (int j = 0; j < n; ++j) {
    e[j] = from_double<S>(1.0);
    inverse_dynamics(bodies, poses, Vec3::Zero().eval(), static_cast<const S*>(nullptr), e.data(), false, work, col);
    e[j] = from_double<S>(0.0);
    for (int i = j; i < n; ++i)
      M[static_cast<std::size_t>(i) * n + j] = M[static_cast<std::size_t>(j) * n + i] = col[i];
  }
  return M;
}

/// M(q), row-major n×n, by the composite-rigid-body algorithm (Featherstone's CRBA) in body
/// frames: the composite inertias (m, h, I) of every subtree, leaves to root, each carried into
/// its parent's frame by transform_inertia; then column j is the force (f, n) on composite body j
/// under a unit joint-j acceleration at rest (f = u × h, n = I u for a revolute joint; f = m u,
/// n = h × u for a prismatic one), carried to the root: M_ij = u_iᵀ n (revolute i) or u_iᵀ f
/// (prismatic i) for every ancestor i of j; M_jj gains the joint's armature. No velocities, no gravity: the straight code the
/// generator records on its tape (src/symbolic/emit_c.cpp), checked against mass_matrix and the
/// fast kernels (tests/generic_dynamics_test.cpp) and, on the tape, against the engine
/// (tests/symbolic_tape_test.cpp).
template <class S>
std::vector<S> crba(const Bodies<S>& bodies, const Poses<S>& poses) {
  const int n = bodies.size();
  std::vector<S> mc(n), M(static_cast<std::size_t>(n) * n, from_double<S>(0.0));
  std::vector<Vec3T<S>> hc(n);
  std::vector<Mat3T<S>> Ic(n);
  for (int i = 0; i < n; ++i) {
    mc[i] = bodies.bodies[i].m;
    hc[i] = bodies.bodies[i].h;
    Ic[i] = bodies.bodies[i].I;
  }
  // composite inertias, leaves to root, each in its body's frame
  for (int i = n; i-- > 0;) {
    const int par = bodies.bodies[i].parent;
    if (par < 0) continue;
    PoseT<S> X;
    X.R = poses.local_R[i];
    X.p = poses.local_p[i];
    Vec3T<S> h = hc[i];
    Mat3T<S> I = Ic[i];
    transform_inertia(X, mc[i], h, I);
    mc[par] = mc[par] + mc[i];
    hc[par] = add(hc[par], h);
    Ic[par] = add(Ic[par], I);
  }
  // column j: the force on the composite body j under a unit joint-j acceleration (at rest),
  // carried to the root
  for (int j = 0; j < n; ++j) {
    const Body<S>& B = bodies.bodies[j];
    const Vec3T<S>& u = B.axis;
    Vec3T<S> f, nn;
    if (B.type == JointType::Revolute) {
      f = cross(u, hc[j]);
      nn = mul(Ic[j], u);
    } else {
      f = scale(u, mc[j]);
      nn = cross(hc[j], u);
    }
    M[static_cast<std::size_t>(j) * n + j] = B.type == JointType::Revolute ? dot(u, nn) : dot(u, f);
    if (!is_zero(B.armature)) M[static_cast<std::size_t>(j) * n + j] = M[static_cast<std::size_t>(j) * n + j] + B.armature;
    for (int i = j; bodies.bodies[i].parent >= 0;) {
      const Vec3T<S> fp = mul(poses.local_R[i], f);
      nn = add(mul(poses.local_R[i], nn), cross(poses.local_p[i], fp));
      f = fp;
      i = bodies.bodies[i].parent;
      const Body<S>& A = bodies.bodies[i];
      M[static_cast<std::size_t>(i) * n + j] = M[static_cast<std::size_t>(j) * n + i] =
          A.type == JointType::Revolute ? dot(A.axis, nn) : dot(A.axis, f);
    }
  }
  return M;
}

}  // namespace refdyn::multibody
