#pragma once
/// Forward kinematics and the kinematics of named points (paper eq. (4.3)):
///   position    r_P = T^(l)(q) r_P^(l)
///   Jacobian    C   = ∂r_P/∂q,          columns T_i^(l) r_P^(l)            (3×n)
///   drift       d   = Σ_ij T_ij^(l) q̇_i q̇_j r_P^(l) = r̈_P − C q̈           (3)
/// All in the world frame {0}. The drift is computed recursively (spatial accelerations with
/// q̈ = 0); trace_dynamics.hpp computes the same quantities the paper's way with T_i, T_ij.

#include "refdyn/model.hpp"

namespace refdyn {

/// Fills data.liMi and data.oMi. q: size nq.
void forward_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q);

/// Inner kernel without argument checks (for hot loops that already validated q).
void forward_kinematics_unchecked(const Model& model, Data& data, const Eigen::VectorXd& q);

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

}  // namespace refdyn
