// Symbolic kinematics and dynamics of a Model (GiNaC): world poses of the bodies, and the
// joint-space inverse dynamics by Newton–Euler in body frames. Nothing is expanded: GiNaC
// shares sub-expressions, and the C writer's common-subexpression elimination keeps them shared.
#include "internal.hpp"

#include <cln/float.h>

#include <cmath>
#include <limits>

namespace refdyn::symbolic_detail {

namespace {

Vec3s add(const Vec3s& a, const Vec3s& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3s sub(const Vec3s& a, const Vec3s& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3s scale(const Vec3s& a, const ex& s) { return {a[0] * s, a[1] * s, a[2] * s}; }
Vec3s cross(const Vec3s& a, const Vec3s& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
ex dot(const Vec3s& a, const Vec3s& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3s mul(const Mat3s& R, const Vec3s& v) {
  return {R[0] * v[0] + R[1] * v[1] + R[2] * v[2], R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
          R[6] * v[0] + R[7] * v[1] + R[8] * v[2]};
}
Mat3s mul(const Mat3s& A, const Mat3s& B) {
  Mat3s C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
  return C;
}
Vec3s vec(const Vec3& v) { return {number(v.x()), number(v.y()), number(v.z())}; }
Vec3s zero3() { return {ex(0), ex(0), ex(0)}; }

/// Rotation entries: within 4 ulp of 0 or ±1 → exact.
ex rotation_entry(double v) {
  const double tol = 4 * std::numeric_limits<double>::epsilon();
  if (std::fabs(v) <= tol) return 0;
  if (std::fabs(v - 1) <= tol) return 1;
  if (std::fabs(v + 1) <= tol) return -1;
  return number(v);
}
Mat3s rotation(const Mat3& R) {
  Mat3s S;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) S[3 * i + j] = rotation_entry(R(i, j));
  return S;
}

}  // namespace

ex number(double v) {
  if (v == std::trunc(v) && std::fabs(v) < 9007199254740992.0) return GiNaC::numeric(static_cast<long>(v));
  return GiNaC::numeric(cln::cl_float(v, cln::float_format_dfloat));
}

/// A vector or matrix of the model with its rounding noise removed: entries within 4 ulp of the
/// largest one are zero (a DH twist of ±90° leaves 6e-17 where the exact value is 0).
Vec3s clean(const Vec3& v) {
  const double tol = 4 * std::numeric_limits<double>::epsilon() * v.cwiseAbs().maxCoeff();
  Vec3 c = v;
  for (int k = 0; k < 3; ++k)
    if (std::fabs(c[k]) <= tol) c[k] = 0;
  return vec(c);
}

SymbolicModel symbolic_model(const Model& model, const std::vector<ex>& q) {
  SymbolicModel s;
  s.model = &model;
  s.q = q;
  const int n = model.nq;
  s.R.resize(n);
  s.r.resize(n);
  for (int i = 0; i < n; ++i) {
    const Mat3s P = rotation(model.placement[i].R);
    const Vec3s p = clean(model.placement[i].p);
    const Vec3& u = model.axis[i];
    const ex x = q[i] + number(model.offset[i]);
    Mat3s Rl = P;  // body orientation in the parent frame
    Vec3s pl = p;  // body origin in the parent frame
    if (model.joint_type[i] == JointType::Revolute) {
      const ex c = GiNaC::cos(x), sn = GiNaC::sin(x);
      const Vec3s a = vec(u);
      // Rodrigues: c 1 + s [u]x + (1 − c) u uᵀ (exact zeros of u drop out)
      Mat3s J;
      const Mat3s K = {ex(0), -a[2], a[1], a[2], ex(0), -a[0], -a[1], a[0], ex(0)};
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) J[3 * r + k] = (r == k ? c : ex(0)) + sn * K[3 * r + k] + (1 - c) * a[r] * a[k];
      Rl = mul(P, J);
    } else {
      pl = add(p, mul(P, scale(vec(u), x)));
    }
    s.local_R.push_back(Rl);
    s.local_p.push_back(pl);
    const int par = model.parent[i];
    if (par < 0) {
      s.R[i] = Rl;
      s.r[i] = pl;
    } else {
      s.R[i] = mul(s.R[par], Rl);
      s.r[i] = add(s.r[par], mul(s.R[par], pl));
    }
  }
  return s;
}

std::vector<ex> SymbolicModel::inverse_dynamics(const std::vector<ex>& qd, const std::vector<ex>& qdd,
                                                bool gravity) const {
  // Newton–Euler with every body quantity in the body's own frame: the joint axis and the
  // inertia are then numbers, and only one joint rotation separates a body from its parent,
  // which keeps the formulas short (a prismatic joint's M_ii is the sliding mass itself).
  const Model& m = *model;
  const int n = m.nq;
  auto at = [](const std::vector<ex>& v, int i) { return v.empty() ? ex(0) : v[i]; };
  std::vector<Vec3s> w(n), wd(n), a(n), f(n), nn(n), pl(n);
  std::vector<Mat3s> Rl(n), E(n);
  const Vec3s a_world = gravity ? scale(vec(m.gravity), -1) : zero3();  // base acceleration −g
  for (int i = 0; i < n; ++i) {
    const int par = m.parent[i];
    Rl[i] = local_R[i];
    pl[i] = local_p[i];
    for (int r0 = 0; r0 < 3; ++r0)
      for (int k = 0; k < 3; ++k) E[i][3 * r0 + k] = Rl[i][3 * k + r0];  // parent → body
    const Vec3s w_p = par < 0 ? zero3() : w[par];
    const Vec3s wd_p = par < 0 ? zero3() : wd[par];
    const Vec3s a_p = par < 0 ? a_world : a[par];
    const Vec3s ax = vec(m.axis[i]);
    const Vec3s w_in = mul(E[i], w_p);  // parent's angular velocity in body axes
    a[i] = mul(E[i], add(add(a_p, cross(wd_p, pl[i])), cross(w_p, cross(w_p, pl[i]))));
    if (m.joint_type[i] == JointType::Revolute) {
      w[i] = add(w_in, scale(ax, at(qd, i)));
      wd[i] = add(add(mul(E[i], wd_p), scale(ax, at(qdd, i))), cross(w_in, scale(ax, at(qd, i))));
    } else {
      w[i] = w_in;
      wd[i] = mul(E[i], wd_p);
      a[i] = add(add(a[i], scale(cross(w_in, ax), 2 * at(qd, i))), scale(ax, at(qdd, i)));
    }
    const Inertia& I = m.inertia[i];
    if (I.m > 0) {
      const Vec3 c = I.h / I.m;
      const Mat3 Ic = I.I + I.m * skew(c) * skew(c);  // about the centre of mass, body axes
      const Vec3s cs = clean(c);
      const Vec3s ac = add(add(a[i], cross(wd[i], cs)), cross(w[i], cross(w[i], cs)));
      f[i] = scale(ac, number(I.m));
      Mat3s Ics;
      const double tol = 4 * std::numeric_limits<double>::epsilon() * Ic.cwiseAbs().maxCoeff();
      for (int r0 = 0; r0 < 3; ++r0)
        for (int k = 0; k < 3; ++k) Ics[3 * r0 + k] = std::fabs(Ic(r0, k)) <= tol ? ex(0) : number(Ic(r0, k));
      nn[i] = add(add(mul(Ics, wd[i]), cross(w[i], mul(Ics, w[i]))), cross(cs, f[i]));  // about the origin
    } else {
      f[i] = zero3();
      nn[i] = zero3();
    }
  }
  std::vector<ex> tau(n);
  for (int i = n; i-- > 0;) {
    const Vec3s ax = vec(m.axis[i]);
    tau[i] = m.joint_type[i] == JointType::Revolute ? dot(ax, nn[i]) : dot(ax, f[i]);
    const int par = m.parent[i];
    if (par >= 0) {
      const Vec3s fp = mul(Rl[i], f[i]);
      f[par] = add(f[par], fp);
      nn[par] = add(add(nn[par], mul(Rl[i], nn[i])), cross(pl[i], fp));
    }
  }
  return tau;
}

}  // namespace refdyn::symbolic_detail
