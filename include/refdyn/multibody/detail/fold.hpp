#pragma once
/// The model fold, written once over a scalar S: a model's links (joints of any type, fixed ones
/// included, each with a link frame offset from its joint frame) become the bodies of the
/// dynamics — one body per moving joint, parents first — and every link a fixed pose in its body.
///
///     joint frame of link i in its body's parent frame:  J_i = (parent's pose in its body) · P_i
///                                                          (the base pose B for a root link)
///     moving joint:  a new body b with placement J_i; link i sits at L_i in body b
///     fixed joint:   link i sits at J_i · L_i in its parent's body; its inertia is added there
///                    (a link fixed to the world adds none)
///     inertia of a link about its own origin, link axes:  m, h = m c, I = I_C − m [c]×²;
///     transformed into its body's frame by the parallel-axis theorem
///     a point on a link: its body, at (the link's pose in its body) · x; on `world`: x; on
///     `base`: B · x, fixed in the world
///
/// Instantiated for double by build_model (model.cpp: the compiled Model) and for GiNaC
/// expressions by the generator (src/symbolic/model.cpp: the model section's numbers, in which a
/// scenario parameter stays a symbol). The DH rows' joint frames (dh_frames) are the same law for
/// both. The pose and inertia arithmetic is FoldAlgebra<S>: the generic core's PoseT and
/// transform_inertia, and for double the spatial algebra's SE3 and Inertia (spatial.hpp), so that
/// build_model's numbers are those it has always had, bit for bit.
#include "refdyn/multibody/body.hpp"
#include "refdyn/multibody/linear3.hpp"
#include "refdyn/multibody/spatial.hpp"

#include <vector>

namespace refdyn::multibody {

/// Mass, first moment h = m c and rotational inertia I about the frame's origin, over S.
template <class S>
struct InertiaT {
  S m = from_double<S>(0.0);
  Vec3T<S> h = zero3<S>();
  Mat3T<S> I = zero33<S>();
};

/// The pose and inertia arithmetic of the fold over S (see the header comment).
template <class S>
struct FoldAlgebra {
  using Pose = PoseT<S>;
  using Inertia = InertiaT<S>;
  using Vec = Vec3T<S>;
  using Mat = Mat3T<S>;
  static Pose identity() { return Pose{}; }
  static Pose rot_x(const S& a) { return multibody::rot_x(a); }
  static Pose rot_z(const S& a) { return multibody::rot_z(a); }
  static Pose trans(const S& x, const S& y, const S& z) { return translation<S>({x, y, z}); }
  static Inertia from_com(const S& m, const Vec& c, const Mat& I_c) {
    return {m, scale(c, m), add(I_c, scale(mul(skew(c), skew(c)), S(-m)))};
  }
  static Inertia transformed(Inertia in, const Pose& X) {
    transform_inertia(X, in.m, in.h, in.I);
    return in;
  }
  static void accumulate(Inertia& a, const Inertia& b) {
    a.m += b.m;
    a.h = add(a.h, b.h);
    a.I = add(a.I, b.I);
  }
  static Vec act(const Pose& X, const Vec& x) { return add(mul(X.R, x), X.p); }
};

template <>
struct FoldAlgebra<double> {
  using Pose = SE3;
  using Inertia = refdyn::Inertia;
  using Vec = Vec3;
  using Mat = Mat3;
  static Pose identity() { return SE3::Identity(); }
  static Pose rot_x(double a) { return SE3::rot_x(a); }
  static Pose rot_z(double a) { return SE3::rot_z(a); }
  static Pose trans(double x, double y, double z) { return SE3::trans(Vec3(x, y, z)); }
  static Inertia from_com(double m, const Vec3& c, const Mat3& I_c) { return Inertia::from_com(m, c, I_c); }
  static Inertia transformed(const Inertia& in, const SE3& X) { return in.transformed(X); }
  static void accumulate(Inertia& a, const Inertia& b) { a += b; }
  static Vec3 act(const SE3& X, const Vec3& x) { return X.act_point(x); }
};

/// A link as the fold reads it.
template <class S>
struct FoldLink {
  using A = FoldAlgebra<S>;
  int parent = -1;                          ///< index of the parent link, −1: the base
  JointType type = JointType::Revolute;
  typename A::Pose placement = A::identity();    ///< P: joint frame in the parent link's frame
  typename A::Pose link_offset = A::identity();  ///< L: link frame in the moved joint frame
  typename A::Inertia inertia;              ///< about the link's origin, link axes (A::from_com)
};

/// The folded model: per body its link, parent, placement and inertia; per link its body.
template <class S>
struct Folded {
  using A = FoldAlgebra<S>;
  std::vector<int> link_of_body;                     ///< the moving link each body is
  std::vector<int> parent;                           ///< parent body, −1: the world
  std::vector<typename A::Pose> placement;           ///< the joint frame in the parent body's
  std::vector<typename A::Inertia> inertia;          ///< about the body origin, body axes
  std::vector<int> body_of;                          ///< per link: its body (−1: the world)
  std::vector<typename A::Pose> link_in_body;        ///< per link: its frame in its body's
  int size() const { return static_cast<int>(parent.size()); }
};

/// Folds the links (parents before children, checked by the caller) on the base pose.
template <class S>
Folded<S> fold_links(const std::vector<FoldLink<S>>& links, const typename FoldAlgebra<S>::Pose& base) {
  using A = FoldAlgebra<S>;
  Folded<S> f;
  const int nl = static_cast<int>(links.size());
  f.body_of.assign(nl, -1);
  f.link_in_body.assign(nl, A::identity());
  for (int i = 0; i < nl; ++i) {
    const FoldLink<S>& l = links[i];
    const int pb = l.parent < 0 ? -1 : f.body_of[l.parent];
    const typename A::Pose joint_in_pb = (l.parent < 0 ? base : f.link_in_body[l.parent]) * l.placement;
    if (l.type == JointType::Fixed) {
      f.body_of[i] = pb;
      f.link_in_body[i] = joint_in_pb * l.link_offset;
      if (pb >= 0) A::accumulate(f.inertia[pb], A::transformed(l.inertia, f.link_in_body[i]));
      continue;
    }
    f.body_of[i] = f.size();
    f.link_in_body[i] = l.link_offset;
    f.link_of_body.push_back(i);
    f.parent.push_back(pb);
    f.placement.push_back(joint_in_pb);
    f.inertia.push_back(A::transformed(l.inertia, l.link_offset));
  }
  return f;
}

/// Where a point goes: `link` is the link's index, or kOnWorld / kOnBase.
inline constexpr int kOnWorld = -1;
inline constexpr int kOnBase = -2;
template <class S>
struct FoldedPoint {
  int body = -1;                              ///< −1: fixed in the world
  typename FoldAlgebra<S>::Vec position;      ///< in the body's frame (the world's for −1)
};
template <class S>
FoldedPoint<S> place_point(const Folded<S>& f, int link, const typename FoldAlgebra<S>::Pose& base,
                           const typename FoldAlgebra<S>::Vec& x) {
  using A = FoldAlgebra<S>;
  if (link == kOnWorld) return {-1, A::act(A::identity(), x)};
  if (link == kOnBase) return {-1, A::act(base, x)};
  return {f.body_of[link], A::act(f.link_in_body[link], x)};
}

/// The joint frames of a DH row: the joint variable enters through θ (revolute) or d
/// (prismatic), the other one is fixed (both for a fixed joint); `offset` is the fixed θ or d
/// of the joint variable. Standard: P = (the part along z), L = Trans_x(a) Rot_x(α);
/// modified: P = Rot_x(α) Trans_x(a) (the part along z), L = 1.
template <class S>
struct DHFrames {
  using A = FoldAlgebra<S>;
  typename A::Pose placement = A::identity(), link_offset = A::identity();
  S offset = from_double<S>(0.0);
};
template <class S>
DHFrames<S> dh_frames(JointType type, const S& theta, const S& d, const S& a, const S& alpha, bool standard) {
  using A = FoldAlgebra<S>;
  const S zero = from_double<S>(0.0);
  typename A::Pose along_z = type == JointType::Prismatic ? A::rot_z(theta) : A::trans(zero, zero, d);
  if (type == JointType::Fixed) along_z = A::rot_z(theta) * A::trans(zero, zero, d);
  DHFrames<S> out;
  out.offset = type == JointType::Prismatic ? d : (type == JointType::Revolute ? theta : zero);
  if (standard) {
    out.placement = along_z;
    out.link_offset = A::trans(a, zero, zero) * A::rot_x(alpha);
  } else {
    out.placement = A::rot_x(alpha) * A::trans(a, zero, zero) * along_z;
  }
  return out;
}

}  // namespace refdyn::multibody
