#pragma once
/// Minimal spatial-vector algebra (Featherstone, "Rigid Body Dynamics Algorithms", ch. 2),
/// written for speed on fixed-size Eigen types. Conventions (see docs/notation.md):
///  - Motion m = (w, v): angular velocity w and the linear velocity v of the point at the
///    frame origin, both in the frame's axes.
///  - Force f = (n, f): moment n about the frame origin and force f.
///  - SE3 X_AB = (R, p): pose of frame B in frame A, x_A = R x_B + p.
///  - Inertia (m, h, I): mass, first moment h = m c (c: centre of mass) and the rotational
///    inertia about the frame origin, all in the frame's axes. This form is additive.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace refdyn {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;

inline Mat3 skew(const Vec3& a) {
  Mat3 s;
  s << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return s;
}

struct Motion {
  Vec3 w = Vec3::Zero();
  Vec3 v = Vec3::Zero();
  static Motion Zero() { return {}; }
  Motion operator+(const Motion& o) const { return {w + o.w, v + o.v}; }
  Motion& operator+=(const Motion& o) {
    w += o.w;
    v += o.v;
    return *this;
  }
  Motion operator*(double s) const { return {w * s, v * s}; }
  /// Motion cross product  this ×m o.
  Motion cross(const Motion& o) const { return {w.cross(o.w), w.cross(o.v) + v.cross(o.w)}; }
};

struct Force {
  Vec3 n = Vec3::Zero();
  Vec3 f = Vec3::Zero();
  static Force Zero() { return {}; }
  Force operator+(const Force& o) const { return {n + o.n, f + o.f}; }
  Force& operator+=(const Force& o) {
    n += o.n;
    f += o.f;
    return *this;
  }
  Force operator-(const Force& o) const { return {n - o.n, f - o.f}; }
};

/// Dual cross product  m ×* f.
inline Force cross_force(const Motion& m, const Force& f) {
  return {m.w.cross(f.n) + m.v.cross(f.f), m.w.cross(f.f)};
}
/// Power pairing  m · f.
inline double dot(const Motion& m, const Force& f) { return m.w.dot(f.n) + m.v.dot(f.f); }

struct SE3 {
  Mat3 R = Mat3::Identity();
  Vec3 p = Vec3::Zero();

  static SE3 Identity() { return {}; }
  SE3 operator*(const SE3& o) const { return {R * o.R, R * o.p + p}; }
  SE3 inverse() const { return {R.transpose(), -(R.transpose() * p)}; }
  Vec3 act_point(const Vec3& x) const { return R * x + p; }
  /// Motion given in B's coordinates expressed in A's coordinates.
  Motion act(const Motion& m) const {
    Vec3 w = R * m.w;
    return {w, R * m.v + p.cross(w)};
  }
  /// Motion given in A's coordinates expressed in B's coordinates.
  Motion act_inv(const Motion& m) const {
    return {R.transpose() * m.w, R.transpose() * (m.v - p.cross(m.w))};
  }
  /// Force given in B's coordinates expressed in A's coordinates.
  Force act(const Force& f) const {
    Vec3 ff = R * f.f;
    return {R * f.n + p.cross(ff), ff};
  }
  Mat4 matrix() const {
    Mat4 T = Mat4::Identity();
    T.topLeftCorner<3, 3>() = R;
    T.topRightCorner<3, 1>() = p;
    return T;
  }
  static SE3 from_matrix(const Mat4& T) { return {T.topLeftCorner<3, 3>(), T.topRightCorner<3, 1>()}; }
  static SE3 rot_x(double a);
  static SE3 rot_z(double a);
  static SE3 trans(const Vec3& p) { return {Mat3::Identity(), p}; }
};

inline SE3 SE3::rot_x(double a) {
  SE3 X;
  X.R = Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix();
  return X;
}
inline SE3 SE3::rot_z(double a) {
  SE3 X;
  X.R = Eigen::AngleAxisd(a, Vec3::UnitZ()).toRotationMatrix();
  return X;
}

struct Inertia {
  double m = 0.0;
  Vec3 h = Vec3::Zero();      ///< first moment m·c
  Mat3 I = Mat3::Zero();      ///< rotational inertia about the frame origin

  static Inertia Zero() { return {}; }
  /// From mass, centre of mass c and inertia I_C about the centre of mass (frame axes).
  static Inertia from_com(double mass, const Vec3& c, const Mat3& I_C) {
    Mat3 sc = skew(c);
    return {mass, mass * c, I_C - mass * sc * sc};
  }
  Inertia operator+(const Inertia& o) const { return {m + o.m, h + o.h, I + o.I}; }
  Inertia& operator+=(const Inertia& o) {
    m += o.m;
    h += o.h;
    I += o.I;
    return *this;
  }
  /// Momentum  I·v.
  Force operator*(const Motion& v) const { return {I * v.w + h.cross(v.v), m * v.v + v.w.cross(h)}; }
  /// This inertia (given in B) expressed in A, for X = X_AB.
  ///   I_A = R I Rᵀ − ([Rh]×[p]× + [p]×[Rh]×) − m [p]×²  =  R I Rᵀ + 2 (k·p) 1 − (p kᵀ + k pᵀ)
  /// with k = R h + ½ m p (from [a]×[b]× = b aᵀ − (a·b) 1); only one triangle is computed.
  Inertia transformed(const SE3& X) const {
    Inertia out;
    transform_into(X, out);
    return out;
  }
  /// Same as transformed(), written into `out` (which must not alias *this).
  void transform_into(const SE3& X, Inertia& out) const {
    const Mat3& R = X.R;
    const Vec3& p = X.p;
    const Vec3 Rh = R * h;
    const Vec3 k = Rh + (0.5 * m) * p;
    const double d = 2.0 * k.dot(p);
    Mat3 A;
    A.noalias() = R * I;  // R I; then (R I) Rᵀ on one triangle
    Mat3& J = out.I;
    for (int c = 0; c < 3; ++c)
      for (int r = c; r < 3; ++r) {
        const double v = A(r, 0) * R(c, 0) + A(r, 1) * R(c, 1) + A(r, 2) * R(c, 2) -
                         (p[r] * k[c] + k[r] * p[c]);
        J(r, c) = v;
        J(c, r) = v;
      }
    J(0, 0) += d;
    J(1, 1) += d;
    J(2, 2) += d;
    out.m = m;
    out.h = Rh + m * p;
  }
  Vec3 com() const { return m > 0 ? Vec3(h / m) : Vec3::Zero(); }
};

}  // namespace refdyn
