#pragma once
/// The paper's route (Jarzębowska et al. 2024, section 2): joint coordinates, 4×4 homogeneous
/// transforms and the matrix trace. For every body l with pose T^(l)(q) and pseudo-inertia H^(l):
///   T_i^(l)  = ∂T^(l)/∂q_i         = D_i T^(l)             (i ancestor of l or l, else 0)
///   T_ij^(l) = ∂²T^(l)/∂q_i∂q_j    = D_a D_b T^(l)         (a = the ancestor of i, j; b the other)
/// with the joint derivative operator D_i = T_i Δ_i T_i⁻¹ (Δ_i the 4×4 twist generator of the
/// joint axis); exact, no finite differences. Then, from Lagrange's equations
/// (derivation in docs/trace_dynamics.md):
///   M_ij = Σ_l tr(T_i^(l) H^(l) T_j^(l)ᵀ)
///   c_i  = Σ_l Σ_jk tr(T_i^(l) H^(l) T_jk^(l)ᵀ) q̇_j q̇_k
///   g_i  = −Σ_l g̃ᵀ T_i^(l) H^(l) e₄,   g̃ = [gravity; 0]
///   T    = ½ Σ_l tr(Ṫ^(l) H^(l) Ṫ^(l)ᵀ),   V = −Σ_l g̃ᵀ T^(l) H^(l) e₄
/// T^(l) here is the pose of the body frame (joint frame after the motion); H^(l) is expressed
/// in it. The result does not depend on this choice of link frame. Cost: O(n³) 4×4 products.

#include "refdyn/multibody/model.hpp"

namespace refdyn {

/// Fills data.T (body poses) and data.D (joint derivative operators). q: size nq.
void trace_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q);

/// T_i^(l) = ∂T^(l)/∂q_i (zero when joint i does not move body l). Requires trace_kinematics.
Mat4 trace_dT(const Model& model, const Data& data, int l, int i);
/// T_ij^(l) = ∂²T^(l)/∂q_i∂q_j. Requires trace_kinematics.
Mat4 trace_ddT(const Model& model, const Data& data, int l, int i, int j);

/// M(q) by the trace formula, plus the joints' armature on the diagonal → data.M_trace.
const Eigen::MatrixXd& trace_mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q);
/// c(q, q̇) by the trace formula → data.c_trace (also fills data.Tdd, data.Td).
const Eigen::VectorXd& trace_coriolis(const Model& model, Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd);
/// g(q) by the trace formula → data.g_trace.
const Eigen::VectorXd& trace_gravity(const Model& model, Data& data, const Eigen::VectorXd& q);
/// Kinetic (armature included: ½ Σ a_i q̇_i²) and potential energy by the trace formulas.
double trace_kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q,
                            const Eigen::VectorXd& qd);
double trace_potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q);

/// Point kinematics the paper's way (4.3): r = T^(l) r^(l), C = [T_1 r, …, T_n r],
/// d = (Σ_ij T_ij q̇_i q̇_j) r. Requires nothing; computes trace_kinematics itself.
struct TracePointKinematics {
  Vec3 position;
  Eigen::Matrix<double, 3, Eigen::Dynamic> C;
  Vec3 d;
};
TracePointKinematics trace_point_kinematics(const Model& model, Data& data, int point,
                                            const Eigen::VectorXd& q, const Eigen::VectorXd& qd);

}  // namespace refdyn
