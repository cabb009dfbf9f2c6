#pragma once
// MuJoCo as a second dynamics peer (beside Orocos KDL, kdl_peer.hpp), for dynamics_bench's
// timings and for tests/mujoco_peer_test.cpp's cross-check.
//
// The peer is built from a compiled refdyn::Model, not from a DH table, so any model refdyn can
// load (DH chains, trees, URDF arms with general axes and prismatic joints, armature) is checked
// against MuJoCo's own algorithms: an MJCF document is written from the model (one <body> per
// refdyn body, nested as the tree is, its placement as pos + quat, a hinge or slide <joint> with
// refdyn's axis and armature, the inertia as mass, centre of mass and the full inertia about the
// centre of mass), MuJoCo compiles it, and the results are mapped back to refdyn's coordinate
// order (MuJoCo numbers the degrees of freedom depth first). A joint offset is added to q before
// it reaches MuJoCo (refdyn's joint angle is q + offset). Contacts and constraints are disabled;
// there is no geometry. MuJoCo's C API holds no Eigen type, so this class is compiled with
// refdyn's own flags and links libmujoco directly (no shared-library boundary as for KDL).
#include "refdyn/multibody/model.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

struct mjModel_;
struct mjData_;

namespace refdyn_bench {

class MujocoPeer {
 public:
  /// Writes the MJCF of `model` and compiles it. Throws std::runtime_error with MuJoCo's message
  /// if MuJoCo rejects it (for instance a moving body without mass: MuJoCo requires mass and
  /// rotational inertia above mjMINVAL on every body that has a joint).
  explicit MujocoPeer(const refdyn::Model& model);
  ~MujocoPeer();
  MujocoPeer(const MujocoPeer&) = delete;
  MujocoPeer& operator=(const MujocoPeer&) = delete;

  /// The MJCF document the constructor compiles.
  static std::string mjcf(const refdyn::Model& model);

  int dof() const { return n_; }

  /// How well MuJoCo's compiled model holds refdyn's inertias: the largest relative difference,
  /// over the bodies, between refdyn's (m, h, I_O) and the one rebuilt from MuJoCo's mass,
  /// centre of mass, principal moments and axes. The dynamics of the two can differ by this much
  /// (times a small factor; for q̈ times cond(M)).
  double inertia_error() const { return inertia_error_; }

  // ---- one call each, arguments and results in refdyn's coordinate order ----
  /// mj_kinematics, mj_comPos, mj_crb (armature included), mj_fullM: the dense M(q).
  const Eigen::MatrixXd& mass_matrix(const Eigen::VectorXd& q);
  /// mj_kinematics, mj_comPos, mj_comVel, mj_rne(flg_acc = 0): c(q, q̇) + g(q).
  const Eigen::VectorXd& bias_forces(const Eigen::VectorXd& q, const Eigen::VectorXd& qd);
  /// mj_kinematics, mj_comPos, mj_comVel, mj_rne(flg_acc = 1) + armature·q̈: M q̈ + c + g.
  const Eigen::VectorXd& inverse_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                          const Eigen::VectorXd& qdd);
  /// MuJoCo's own inverse dynamics, mj_inverse (its whole pipeline, qfrc_inverse), as a second
  /// route inside MuJoCo.
  const Eigen::VectorXd& inverse_dynamics_pipeline(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                   const Eigen::VectorXd& qdd);
  /// mj_kinematics, mj_comPos, mj_crb, mj_factorM, mj_comVel, mj_rne(0), mj_solveM: q̈ = M⁻¹(τ − c − g).
  const Eigen::VectorXd& forward_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                          const Eigen::VectorXd& tau);

  // ---- the timed kernels: stored states, results left in MuJoCo's order inside ----
  /// Stores `count` states in MuJoCo's order (q with its offsets added).
  void load_states(const std::vector<Eigen::VectorXd>& q, const std::vector<Eigen::VectorXd>& qd,
                   const std::vector<Eigen::VectorXd>& qdd, const std::vector<Eigen::VectorXd>& tau);
  void time_mass_matrix(int k);       ///< as mass_matrix, on stored state k
  void time_bias_forces(int k);       ///< as bias_forces
  void time_inverse_dynamics(int k);  ///< as inverse_dynamics
  void time_forward_dynamics(int k);  ///< as forward_dynamics
  /// The result of the last call, in refdyn's order (for tests of the timed kernels).
  const Eigen::MatrixXd& last_mass_matrix();
  const Eigen::VectorXd& last_bias_forces();
  const Eigen::VectorXd& last_tau();
  const Eigen::VectorXd& last_qdd();

 private:
  void set_state(const double* q_mj, const double* qd_mj);  // MuJoCo order, offsets included
  /// q (offsets added) and, when given, q̇ and q̈ from refdyn's order into qpos, qvel, qacc.
  void to_mj_state(const Eigen::VectorXd& q, const Eigen::VectorXd* qd, const Eigen::VectorXd* qdd);
  /// Stored state k of one of sq_, sqd_, sqdd_, stau_.
  const double* stored(const std::vector<double>& v, int k) const { return v.data() + static_cast<size_t>(k) * n_; }
  void to_mj(const Eigen::VectorXd& x, double* out, bool add_offset) const;
  void from_mj(const double* x, Eigen::VectorXd& out) const;
  void run_mass_matrix();
  void run_bias_forces();
  void run_inverse_dynamics();
  void run_forward_dynamics(const double* tau_mj);

  int n_ = 0;
  double inertia_error_ = 0.0;
  mjModel_* m_ = nullptr;
  mjData_* d_ = nullptr;
  std::vector<int> dof_;         ///< MuJoCo dof index of refdyn coordinate i
  std::vector<double> offset_;   ///< refdyn's joint offsets
  std::vector<double> armature_; ///< per MuJoCo dof
  std::vector<double> Mfull_, tmp_, out_;
  std::vector<double> sq_, sqd_, sqdd_, stau_;  ///< stored states, MuJoCo order
  Eigen::MatrixXd M_;
  Eigen::VectorXd v_;
};

}  // namespace refdyn_bench
