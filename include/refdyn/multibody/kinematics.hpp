#pragma once
/// Forward kinematics and the kinematics of named points (paper eq. (4.3)):
///   position    r_P = T^(l)(q) r_P^(l)
///   Jacobian    C   = ∂r_P/∂q,          columns T_i^(l) r_P^(l)            (3×n)
///   drift       d   = Σ_ij T_ij^(l) q̇_i q̇_j r_P^(l) = r̈_P − C q̈           (3)
/// All in the world frame {0}. The drift is computed recursively (spatial accelerations with
/// q̈ = 0); trace_dynamics.hpp computes the same quantities the paper's way with T_i, T_ij.

#include "refdyn/multibody/model.hpp"

namespace refdyn {

/// Fills data.liMi and data.oMi. q: size nq.
void forward_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q);

namespace unchecked {
/// forward_kinematics without the size, finiteness and Data checks (callers guarantee them).
void forward_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q);
}  // namespace unchecked

/// Joint transform of body i in its parent: placement_i · J_i(q_i).
SE3 joint_placement(const Model& model, int i, double qi);

/// Position of point `point` in {0}. Requires forward_kinematics.
Vec3 point_position(const Model& model, const Data& data, int point);

/// Fills data.Jp with the point Jacobian C (3×nq, world frame) and data.Jw with the angular
/// Jacobian of the point's body. Requires forward_kinematics.
void point_jacobian(const Model& model, Data& data, int point);

/// Pose of a link's user frame (e.g. the DH frame) in {0}: T^(l). Requires forward_kinematics.
SE3 link_transform(const Model& model, const Data& data, int body);

/// Velocity-product (drift) term d of point `point` (world frame) and the angular velocity
/// ω and drift angular acceleration ω̇|_{q̈=0} of its body. Requires forward_kinematics; uses
/// data.v and data.a as scratch.
struct PointDrift {
  Vec3 velocity;        ///< ṙ_P = C q̇
  Vec3 drift;           ///< d = r̈_P − C q̈
  Vec3 omega;           ///< angular velocity of the body carrying P
  Vec3 omega_drift;     ///< ω̇ − Jw q̈
};
PointDrift point_drift(const Model& model, Data& data, int point, const Eigen::VectorXd& qd);

/// Building blocks shared by point_jacobian / point_drift and the constraint kinematics
/// (compute_point_states); no argument checks.
namespace kinematics_detail {
/// data.v[i], data.a[i]: body i's spatial velocity and drift acceleration (q̈ = 0) in its own
/// frame, from its parent's (which must be done). Requires data.liMi.
void propagate_velocity_drift(const Model& model, Data& data, int i, const Eigen::VectorXd& qd);
/// C and Jw (3×n, zeroed first) of a point at world position r on body b. Requires data.oMi.
void point_jacobian_at(const Model& model, const Data& data, int b, const Vec3& r,
                       Eigen::Matrix<double, 3, Eigen::Dynamic>& C, Eigen::Matrix<double, 3, Eigen::Dynamic>& Jw);
/// World-frame velocity, drift, ω and ω̇-drift of the point r_body (body frame) on body b, from
/// data.v[b], data.a[b] and data.oMi[b].
PointDrift point_drift_on_body(const Data& data, int b, const Vec3& r_body);
}  // namespace kinematics_detail

}  // namespace refdyn
