#pragma once
/// The bodies of a compiled model over a scalar S (double, a dual number, or a GiNaC expression
/// whose geometry and inertia may be symbols of scenario parameters).
///
///     body i's frame in its parent's = P_i · J_i(q_i + offset_i),   P_i = (R, p)
///     J_i = rotation by the angle about `axis` (revolute) or translation along it (prismatic)
///     inertia about the body origin, body axes: m, h = m c, I = I_C − m [c]×²
///     armature a: a joint-space inertia, M_ii += a (the rotor inertia reflected to the joint)
///
/// One body per degree of freedom, parents before children, fixed joints and link offsets
/// folded, exactly as build_model compiles a Model (model.hpp); a point is fixed on one body.
#include "refdyn/multibody/model.hpp"
#include "refdyn/multibody/linear3.hpp"

#include <vector>

namespace refdyn::multibody {

template <class S>
struct Body {
  int parent = -1;                  ///< parent body, -1: the world
  JointType type = JointType::Revolute;  ///< Revolute or Prismatic
  Vec3T<S> axis = zero3<S>();       ///< unit joint axis in the body frame
  Mat3T<S> R = identity3<S>();      ///< placement P of the joint frame in the parent body frame
  Vec3T<S> p = zero3<S>();
  S offset = from_double<S>(0.0);   ///< joint offset (angle or distance)
  S m = from_double<S>(0.0);        ///< mass
  Vec3T<S> h = zero3<S>();          ///< first moment m·c, body frame
  Mat3T<S> I = zero33<S>();         ///< rotational inertia about the body origin, body axes
  S armature = from_double<S>(0.0); ///< joint armature (Model::armature), added to M_ii
};

template <class S>
struct Point {
  int body = -1;                    ///< -1: fixed in the world
  Vec3T<S> position = zero3<S>();   ///< in the body frame (the world frame for body −1)
};

template <class S>
struct Bodies {
  std::vector<Body<S>> bodies;
  std::vector<Point<S>> points;     ///< indexed like Model::point_name
  int size() const { return static_cast<int>(bodies.size()); }
};

/// How the compiled model's doubles become S constants: exactly. (The generator passes its own
/// policy, which writes entries within a few ulp of 0 or ±1 exactly: src/symbolic/model.cpp.)
template <class S>
struct ExactLift {
  S scalar(double v) const { return from_double<S>(v); }
  Vec3T<S> axis(const Vec3& v) const { return lift<S>(v); }
  Vec3T<S> vector(const Vec3& v) const { return lift<S>(v); }
  Mat3T<S> rotation(const Mat3& R) const { return lift<S>(R); }
  Mat3T<S> inertia(const Mat3& I) const { return lift<S>(I); }
};

/// The compiled model's bodies and points over S, each number through `to` (Pinocchio's
/// ModelTpl::cast).
template <class S, class Lift = ExactLift<S>>
Bodies<S> bodies_from_model(const Model& model, const Lift& to = Lift{}) {
  Bodies<S> out;
  out.bodies.resize(model.nv);
  for (int i = 0; i < model.nv; ++i) {
    Body<S>& b = out.bodies[i];
    b.parent = model.parent[i];
    b.type = model.joint_type[i];
    b.axis = to.axis(model.axis[i]);
    b.R = to.rotation(model.placement[i].R);
    b.p = to.vector(model.placement[i].p);
    b.offset = to.scalar(model.offset[i]);
    b.m = to.scalar(model.inertia[i].m);
    b.h = to.vector(model.inertia[i].h);
    b.I = to.inertia(model.inertia[i].I);
    b.armature = to.scalar(model.armature[i]);
  }
  for (std::size_t k = 0; k < model.point_name.size(); ++k)
    out.points.push_back({model.point_body[k], to.vector(model.point_position[k])});
  return out;
}

/// Inertia (m, h, I about the origin) given in frame B, expressed in A for the pose X of B in A
/// (parallel axes): h' = R h + m p, I' = R I Rᵀ − [p]×[Rh]× − [Rh]×[p]× − m [p]×².
template <class S>
void transform_inertia(const PoseT<S>& X, const S& m, Vec3T<S>& h, Mat3T<S>& I) {
  const Vec3T<S> Rh = mul(X.R, h);
  const Mat3T<S> P = skew(X.p), H = skew(Rh);
  I = add(add(mul(mul(X.R, I), transpose(X.R)), scale(add(mul(P, H), mul(H, P)), from_double<S>(-1.0))),
          scale(mul(P, P), S(-m)));
  h = add(Rh, scale(X.p, m));
}

}  // namespace refdyn::multibody
