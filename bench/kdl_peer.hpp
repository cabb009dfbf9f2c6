#pragma once
// Orocos KDL as a benchmark peer, behind a plain interface (raw doubles in and out).
//
// Debian's KDL is built for baseline x86-64 (SSE2) while refdyn is compiled with
// -march=native. Eigen objects allocated under one alignment setting and freed under another
// crash, and inline Eigen functions compiled both ways would be merged by the linker, so the
// KDL side lives in its own shared library (refdyn_kdl_peer), compiled with the default flags
// and hidden visibility: nothing but this class crosses the boundary, and no Eigen or KDL type
// appears in this header.

#include "dh_tables.hpp"

#include <memory>
#include <string>

#if defined(__GNUC__)
#define REFDYN_KDL_PEER_API __attribute__((visibility("default")))
#else
#define REFDYN_KDL_PEER_API
#endif

namespace refdyn_bench {

class REFDYN_KDL_PEER_API KdlPeer {
 public:
  /// Builds a KDL::Chain from the standard-DH table: one segment per row with
  /// Joint::RotZ / Joint::TransZ, tip frame KDL::Frame::DH(a, α, d, θ) and
  /// KDL::RigidBodyInertia(m, com, I_com) (KDL takes the rotational inertia about the COM); a
  /// row's armature is the joint's inertia (KDL::Joint's `inertia`).
  explicit KdlPeer(const DHTable& table);
  ~KdlPeer();
  KdlPeer(const KdlPeer&) = delete;
  KdlPeer& operator=(const KdlPeer&) = delete;

  int dof() const;

  /// Stores `count` states (each argument: count × n doubles, state k at offset k·n).
  void load_states(const double* q, const double* qd, const double* qdd, int count);

  // The timed kernels, on stored state k; results stay inside (see the getters). Each returns
  // KDL's error code (0 on success).
  int mass_matrix(int k);                 ///< ChainDynParam::JntToMass
  int coriolis(int k);                    ///< ChainDynParam::JntToCoriolis
  int gravity(int k);                     ///< ChainDynParam::JntToGravity
  int inverse_dynamics(int k);            ///< ChainIdSolver_RNE::CartToJnt (no external wrenches)

  // ---- forward dynamics ----
  /// Stores `count` joint-torque vectors (count × n doubles, state k at offset k·n) for the two
  /// forward-dynamics kernels below.
  void load_torques(const double* tau, int count);
  /// KDL's own forward dynamics, ChainFdSolver_RNE::CartToJnt (JntToMass + RNE with q̈ = 0 +
  /// KDL's LDLᵀ), on stored state k and torques k → get_qdd.
  int forward_dynamics(int k);
  /// Constrained forward dynamics with KDL's dynamics: JntToMass, JntToCoriolis, JntToGravity,
  /// then the KKT system [[M, Aᵀ], [A, 0]] [q̈; λ] = [−c − g; rhs] (no applied forces) by Eigen (LLT of M and of
  /// the Schur complement A M⁻¹ Aᵀ, workspaces allocated once) → get_qdd. A and rhs come
  /// precomputed from set_constraints (KDL has no constraint model of its own).
  int constrained_forward_dynamics(int k);
  /// Per state k: A (m × n, column-major, offset k·m·n) and rhs (m, offset k·m).
  void set_constraints(const double* A, const double* rhs, int m, int count);
  void get_qdd(double* qdd) const;

  void get_mass_matrix(double* M_colmajor) const;  ///< n × n
  void get_coriolis(double* c) const;
  void get_gravity(double* g) const;
  void get_tau(double* tau) const;

  // ---- Vereshchagin hybrid dynamics (KDL::ChainHdSolver_Vereshchagin) ----
  // Six-vectors here are [linear x, y, z; angular x, y, z] (KDL's Twist / Jacobian row order).

  /// Creates the solver with `nc` end-effector constraints and the root acceleration
  /// `root_acc` (6). KDL's convention: root_acc is the acceleration of the base, i.e. MINUS
  /// gravity (e.g. [0, 0, +9.81, 0, 0, 0] for gravity −9.81 z).
  void setup_vereshchagin(const double* root_acc, int nc);
  /// Stores the solver inputs for `count` states (used with the q, q̇ of load_states): per state
  /// k, alfa (6 × nc, column-major, offset k·6·nc: unit constraint forces in the base frame,
  /// applied at the tip), beta (nc, offset k·nc) and ff_torques (n, offset k·n). f_ext is zero.
  void load_vereshchagin_inputs(const double* alfa, const double* beta, const double* ff_torques, int count);
  /// The timed kernel: ChainHdSolver_Vereshchagin::CartToJnt on stored state k. Returns KDL's
  /// error code (0 on success).
  int vereshchagin(int k);
  void get_vereshchagin_qdd(double* qdd) const;                   ///< n
  void get_vereshchagin_constraint_torques(double* tau_c) const;  ///< n
  void get_vereshchagin_nu(double* nu) const;                     ///< nc (constraint force magnitudes)
  /// The solver's own spatial acceleration of the last segment (getTransformedLinkAcceleration:
  /// base orientation, reference point at the tip; it includes root_acc).
  void get_vereshchagin_tip_acceleration(double* acc6) const;

  /// Tip kinematics of stored state k with joint accelerations `qdd`, from KDL's kinematic
  /// solvers (not the dynamics solver): ChainFkSolverVel_recursive gives the tip position (3)
  /// and twist (6, base frame, reference point at the tip); ChainJntToJacSolver and
  /// ChainJntToJacDotSolver (hybrid representation) give acc6 = J q̈ + J̇ q̇, the classical
  /// acceleration [r̈_tip; ω̇]. Returns 0 on success.
  int tip_kinematics(int k, const double* qdd, double* pos3, double* twist6, double* acc6);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A URDF file loaded by KDL's own parser (kdl_parser::treeFromFile, Debian libkdl-parser-dev)
/// into a KDL::Tree, and its inverse dynamics by KDL::TreeIdSolver_RNE: an independent reading of
/// the same file as refdyn's loader (io/urdf.hpp), for the start-up check of dynamics_bench.
/// KDL reads a <mimic> joint as an ordinary joint, as refdyn's model does (refdyn adds the
/// coupling as a constraint).
class REFDYN_KDL_PEER_API KdlUrdfPeer {
 public:
  /// Throws std::runtime_error if kdl_parser cannot read the file. gravity: 3 doubles.
  KdlUrdfPeer(const std::string& urdf_path, const double* gravity);
  ~KdlUrdfPeer();
  KdlUrdfPeer(const KdlUrdfPeer&) = delete;
  KdlUrdfPeer& operator=(const KdlUrdfPeer&) = delete;

  int dof() const;
  /// The URDF joint name of KDL's coordinate i (KDL numbers the moving joints itself).
  std::string joint_name(int i) const;
  /// τ = M(q) q̈ + c(q, q̇) + g(q) by TreeIdSolver_RNE::CartToJnt, no external wrenches; all in
  /// KDL's coordinate order. Returns KDL's error code (0 on success).
  int inverse_dynamics(const double* q, const double* qd, const double* qdd, double* tau);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace refdyn_bench
