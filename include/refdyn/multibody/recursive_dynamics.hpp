#pragma once
/// Recursive rigid-body dynamics on spatial vectors (Featherstone 2008). Sign convention:
///     M(q) q̈ + c(q, q̇) + g(q) = τ
/// with c the Coriolis/centrifugal vector and g the gravity vector (g = ∂V/∂q).
/// These are the independent cross-check of the paper's trace route (trace_dynamics.hpp),
/// and the fast route used by the planners and controllers.

#include "refdyn/common/crossovers.hpp"
#include "refdyn/multibody/model.hpp"

namespace refdyn {

/// Recursive Newton–Euler algorithm: τ = M(q) q̈ + c(q, q̇) + g(q) → data.tau.
/// q, qd, qdd: size nq. O(n).
const Eigen::VectorXd& inverse_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd);

/// Bias forces c(q, q̇) + g(q) (RNEA with q̈ = 0) → data.nle.
const Eigen::VectorXd& bias_forces(const Model& model, Data& data, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qd);

/// Gravity vector g(q) (RNEA with q̇ = q̈ = 0) → data.g.
const Eigen::VectorXd& gravity_forces(const Model& model, Data& data, const Eigen::VectorXd& q);

/// Composite rigid-body algorithm: joint-space mass matrix M(q) → data.M (both triangles).
/// Also leaves data.liMi filled. O(n·depth).
const Eigen::MatrixXd& mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q);

/// (kAbaFrom, the crossover to the articulated-body algorithm: refdyn/common/crossovers.hpp)

/// True when forward_dynamics uses the articulated-body algorithm for a model of nq coordinates.
constexpr bool forward_dynamics_uses_aba(int nq) { return nq >= kAbaFrom; }

/// Forward dynamics q̈ = M⁻¹ (τ − c − g) → data.ddq, by the faster algorithm for the model's size:
/// forward_dynamics_aba from kAbaFrom coordinates on, else forward_dynamics_crba (the result is
/// exactly the chosen one's; see those for what else they leave in data).
const Eigen::VectorXd& forward_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& tau);

/// Forward dynamics via CRBA + RNEA + Cholesky → data.ddq. O(n²) + O(n³/6).
/// Also leaves data.M, data.nle and data.llt (factor of M) filled.
const Eigen::VectorXd& forward_dynamics_crba(const Model& model, Data& data, const Eigen::VectorXd& q,
                                             const Eigen::VectorXd& qd, const Eigen::VectorXd& tau);

/// Forward dynamics via Featherstone's articulated-body algorithm (in the world frame) → data.ddq.
/// O(n). Leaves data.liMi, data.oMi and the scratch data.aba, data.Ic; not data.M or data.nle.
const Eigen::VectorXd& forward_dynamics_aba(const Model& model, Data& data, const Eigen::VectorXd& q,
                                            const Eigen::VectorXd& qd, const Eigen::VectorXd& tau);

/// Kinetic energy ½ q̇ᵀ M q̇ and potential energy V = −Σ m_l gᵀ r_C,l (zero at the origin of
/// {0}), computed recursively (independent of the trace route's energies).
double kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd);
double potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q);

namespace unchecked {
/// Kernels without argument checks, for inner loops whose inputs were validated once.
void rnea(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
          const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out);
void crba(const Model& model, Data& data, const Eigen::VectorXd& q);
/// RNEA reusing the joint placements data.liMi left by crba for the same q (no joint sincos).
void rnea_reusing_placements(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
                             const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out);
/// data.M = M(q) and data.nle = c(q, q̇) + g(q) together (what crba followed by
/// rnea_reusing_placements(q, &q̇, nullptr, true, data.nle) gives, and the same data.liMi,
/// data.v, data.a): for small models in one forward and one backward sweep.
void mass_matrix_and_bias(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd);
/// Articulated-body algorithm: qdd = M⁻¹ (tau − c − g) (qdd may be any of the inputs or
/// data.ddq). Returns −1, or the first body (in backward order) whose articulated inertia about
/// its joint axis is not positive, i.e. M(q) is not positive definite (qdd unspecified).
int aba(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
        const Eigen::VectorXd& tau, Eigen::VectorXd& qdd);
/// x = M(q)⁻¹ tau (n values each; x may be tau) for the q of the last successful aba call on this
/// data, reusing its articulated-body factorization: two O(n) sweeps.
void aba_solve(const Model& model, Data& data, const double* tau, double* x);
/// Solves data.M x = b in place by Cholesky (fixed-size for up to 4 coordinates, else data.llt);
/// false, with b unspecified, when data.M is not positive definite.
bool solve_mass_matrix(Data& data, Eigen::VectorXd& b);
}  // namespace unchecked

}  // namespace refdyn
