#pragma once
/// The multibody model: an editable description (what builders and parsers produce), compiled
/// by build_model() into an immutable Model, and a Data workspace sized once from it.
///
/// Kinematic tree. Every link l has a joint connecting it to its parent (another link, or the
/// base). The pose of link l's frame in the world frame {0} is
///     T^(l) = T^(parent) · P_l · J_l(q_l) · L_l
/// with P_l the fixed placement of the joint frame in the parent link frame, J_l the joint
/// motion (rotation by q_l + offset about `axis`, or translation by q_l + offset along it,
/// or identity for a fixed joint) and L_l a fixed transform from the joint frame to the link
/// frame. Standard DH: P = Tz(d) (revolute) or Rz(θ) (prismatic), L = Tx(a)·Rx(α).
/// Modified (Craig) DH: P = Rx(α)·Tx(a)·(Tz(d) or Rz(θ)), L = 1.
///
/// Build_model folds fixed joints into their parent and L_l into children, so that the
/// compiled Model has one *body* per degree of freedom, whose frame is the joint frame after
/// the motion; the body's inertia, children placements and points are expressed in it.

#include "refdyn/multibody/spatial.hpp"

#include <Eigen/Core>
#include <Eigen/Cholesky>
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace refdyn {

enum class JointType { Revolute, Prismatic, Fixed };

const char* to_string(JointType t);

/// Optional joint limits, used by feasibility reports; infinite means "no limit".
struct JointLimits {
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  double velocity = std::numeric_limits<double>::infinity();
  double effort = std::numeric_limits<double>::infinity();
};

/// Mass properties of a link in its own link frame.
struct LinkInertia {
  double mass = 0.0;
  Vec3 com = Vec3::Zero();          ///< centre of mass r_C in the link frame [m]
  Mat3 I_com = Mat3::Zero();        ///< inertia about the centre of mass, link axes [kg m²]
};

struct LinkSpec {
  std::string name;
  std::string joint_name;           ///< defaults to the link name
  int parent = -1;                  ///< index of the parent link in ModelDescription::links, -1: base
  JointType type = JointType::Revolute;
  SE3 placement;                    ///< P: joint frame in the parent link frame
  Vec3 axis = Vec3::UnitZ();        ///< joint axis in the joint frame (unit vector)
  double offset = 0.0;              ///< joint offset: angle (revolute) or distance (prismatic)
  SE3 link_offset;                  ///< L: link frame in the moved joint frame
  LinkInertia inertia;
  JointLimits limits;
  /// Armature (rotor inertia reflected through the gear, I_r N², as MuJoCo and Drake call it)
  /// [kg m² for a revolute joint, kg for a prismatic one]: a joint-space inertia added to the
  /// joint's diagonal entry of M (τ_i gains armature·q̈_i; no gyroscopic effect of the rotor).
  /// 0 for a fixed joint.
  double armature = 0.0;
};

struct PointSpec {
  std::string name;
  std::string link;                 ///< name of the link the point is attached to
  Vec3 position = Vec3::Zero();     ///< in that link's frame
};

/// A link's visual geometry (a URDF <visual>): what the report draws; no part of the dynamics.
struct VisualSpec {
  enum class Shape { Mesh, Box, Cylinder, Sphere };
  std::string link;                 ///< the link it is attached to
  SE3 origin;                       ///< its pose in the link frame
  Shape shape = Shape::Mesh;
  Vec3 size = Vec3::Ones();         ///< box: edge lengths [m]; mesh: scale per axis
  double radius = 0, length = 0;    ///< cylinder (along z: radius, length), sphere (radius) [m]
  std::string uri;                  ///< mesh: the file name as written (package://, file://, a path)
  std::string file;                 ///< mesh: the file it resolves to; empty when it did not (`note`)
  std::string note;                 ///< why a mesh did not resolve
  bool has_color = false;
  std::array<double, 4> rgba{0.7, 0.7, 0.7, 1.0};  ///< material colour (has_color)
};

struct ModelDescription {
  std::string name = "model";
  SE3 base;                         ///< pose of the base frame in the world frame {0}
  Vec3 gravity = Vec3(0, 0, -9.81); ///< gravity acceleration in {0} [m/s²]
  std::vector<LinkSpec> links;
  std::vector<PointSpec> points;
  std::vector<VisualSpec> visuals;  ///< drawn by the report (URDF <visual>); ignored by build_model

  /// Appends a link and returns its index.
  int add_link(const LinkSpec& l);
  /// Attaches a named point to a link; returns *this for chaining.
  ModelDescription& add_point(const std::string& name, const std::string& link, const Vec3& p);
};

enum class DHConvention { Standard, Modified };

/// One row of a Denavit–Hartenberg table. For a revolute joint θ is the offset added to q;
/// for a prismatic joint d is.
struct DHRow {
  JointType type = JointType::Revolute;
  double theta = 0.0, d = 0.0, a = 0.0, alpha = 0.0;
  LinkInertia inertia;
  JointLimits limits;
  std::string name;
};

/// A serial chain from a DH table (link i's parent is link i-1).
ModelDescription from_dh(const std::vector<DHRow>& rows, DHConvention conv = DHConvention::Standard,
                         const std::string& name = "dh_chain");

class Model;
/// Validates the description (masses, inertias, parents, names, finiteness) and compiles it.
/// Throws refdyn::Error naming the offending link/point and what to change.
Model build_model(const ModelDescription& d);

/// The contents of a compiled model, as build_model fills them (then frozen into a Model).
struct ModelData {
  int nq = 0;                       ///< number of generalized coordinates (= nv)
  int nv = 0;
  std::string name;
  std::uint64_t id = 0;             ///< distinct for every build_model call (copies share it)
  Vec3 gravity = Vec3(0, 0, -9.81);

  // --- per body (index = coordinate index) ---
  std::vector<int> parent;          ///< parent body, -1 for the world
  std::vector<JointType> joint_type;///< Revolute or Prismatic
  std::vector<SE3> placement;       ///< joint frame in parent body frame (base folded in for roots)
  std::vector<Vec3> axis;           ///< unit joint axis in the body frame
  std::vector<double> offset;       ///< joint offset
  std::vector<Inertia> inertia;     ///< spatial inertia in the body frame
  std::vector<SE3> link_offset;     ///< user link frame in body frame (for link_transform)
  std::vector<std::string> body_name, joint_name;
  std::vector<JointLimits> limits;
  std::vector<std::vector<int>> support; ///< ancestors of body i including i, root first
  std::vector<double> armature;     ///< joint armature, added to M_ii (LinkSpec::armature)

  // --- points ---
  std::vector<std::string> point_name;
  std::vector<int> point_body;      ///< body index, -1: fixed in the world
  std::vector<Vec3> point_position; ///< in the body frame (world frame when body is -1)

  // --- link frames (every link of the description, fixed ones included, in its order) ---
  std::vector<std::string> frame_name;
  std::vector<int> frame_body;      ///< the body the link was folded into, -1: the world
  std::vector<SE3> frame_pose;      ///< the link frame in that body's frame (world frame, base included, for -1)
};

/// Immutable compiled model: one body per degree of freedom, parents before children. Made only
/// by build_model (which validates the description); every member is const, so a Model (and any
/// Data or algorithm that refers to it) cannot be changed after build_model returns. Copies share
/// its id.
class Model {
 public:
  const int nq = 0;                 ///< number of generalized coordinates (= nv)
  const int nv = 0;
  const std::string name;
  const std::uint64_t id = 0;             ///< distinct for every build_model call (copies share it)
  const Vec3 gravity = Vec3(0, 0, -9.81);

  // --- per body (index = coordinate index) ---
  const std::vector<int> parent;          ///< parent body, -1 for the world
  const std::vector<JointType> joint_type;///< Revolute or Prismatic
  const std::vector<SE3> placement;       ///< joint frame in parent body frame (base folded in for roots)
  const std::vector<Vec3> axis;           ///< unit joint axis in the body frame
  const std::vector<double> offset;       ///< joint offset
  const std::vector<Inertia> inertia;     ///< spatial inertia in the body frame
  const std::vector<SE3> link_offset;     ///< user link frame in body frame (for link_transform)
  const std::vector<std::string> body_name, joint_name;
  const std::vector<JointLimits> limits;
  const std::vector<std::vector<int>> support; ///< ancestors of body i including i, root first
  /// Joint armature a_i (LinkSpec::armature), part of the dynamics in every route:
  /// M = M_rigid + diag(a), τ = M q̈ + c + g, T = ½ q̇ᵀ M q̇.
  const std::vector<double> armature;

  // --- points ---
  const std::vector<std::string> point_name;
  const std::vector<int> point_body;      ///< body index, -1: fixed in the world
  const std::vector<Vec3> point_position; ///< in the body frame (world frame when body is -1)

  // --- link frames: every link of the description (fixed ones included, in its order), the
  // body it was folded into (-1: the world) and its pose in that body's frame (for -1 in the
  // world frame, the base included); what draws a link's own geometry (the report's meshes) ---
  const std::vector<std::string> frame_name;
  const std::vector<int> frame_body;
  const std::vector<SE3> frame_pose;

  int body_index(const std::string& link_name) const;  ///< throws with "did you mean"
  int point_index(const std::string& point) const;     ///< throws with "did you mean"
  int joint_index(const std::string& joint) const;     ///< throws with "did you mean"
  /// Motion subspace S_i of body i in its own frame.
  Motion motion_subspace(int i) const {
    return joint_type[i] == JointType::Revolute ? Motion{axis[i], Vec3::Zero()}
                                                : Motion{Vec3::Zero(), axis[i]};
  }
  /// Pseudo-inertia matrix H = [[J, m r_C],[m r_Cᵀ, m]] of body i in its body frame,
  /// J = ∫ r rᵀ dm = ½ tr(I_O)·1 − I_O.
  Mat4 pseudo_inertia(int i) const;
  /// Total mass.
  double total_mass() const;
  /// Multi-line human-readable summary.
  std::string summary() const;
  /// Checks size and finiteness of q (throws with the joint names in the hint).
  void check_q(const Eigen::VectorXd& q, const char* what = "q") const;

 private:
  friend Model build_model(const ModelDescription& d);
  explicit Model(ModelData d);
};

/// Per-body scratch of the articulated-body algorithm (forward_dynamics_aba), in the world
/// frame {0}. Spatial vectors are [angular; linear] about the world origin, each part padded to
/// four doubles (the kernels load and store them as 4-lane SIMD registers).
struct AbaBody {
  double S[2][4];                   ///< joint axis S_i
  double v[2][4];                   ///< body velocity v_i
  double c[2][4];                   ///< velocity-product acceleration v_i ×m S_i q̇_i
  double p[2][4];                   ///< articulated bias force p_i
  double U[2][4];                   ///< U_i = IA_i S_i
  double a[2][4];                   ///< body acceleration a_i (trees only)
  double Ia[6][2][4];               ///< children's articulated inertias (trees only; 6 columns)
  double Dinv = 0;                  ///< 1 / (S_iᵀ U_i)
};

/// Workspace for the algorithms; allocated once by the constructor, never resized afterwards.
/// Each field says which function fills it.
struct Data {
  explicit Data(const Model& model);

  std::uint64_t model_id;           ///< Model::id of the model it was built for
  int nq;                           ///< that model's number of coordinates

  // forward_kinematics
  std::vector<SE3> liMi;            ///< body i in its parent's frame
  std::vector<SE3> oMi;             ///< body i in the world frame
  // inverse_dynamics / bias_forces / gravity_forces
  std::vector<Motion> v, a;         ///< body velocities and accelerations (body frame)
  std::vector<Force> f;             ///< body forces (body frame)
  Eigen::VectorXd tau;              ///< result of inverse_dynamics
  Eigen::VectorXd nle;              ///< c(q,q̇) + g(q), result of bias_forces
  Eigen::VectorXd g;                ///< g(q), result of gravity_forces
  // mass_matrix
  std::vector<Inertia> Ic;          ///< composite inertias (scratch of mass_matrix: body frames below
                                    ///< 7 bodies, the world frame {0} from 7 on); forward_dynamics_aba:
                                    ///< the body inertias in {0}
  Eigen::MatrixXd M;                ///< joint-space mass matrix (both triangles filled)
  // forward_dynamics (CRBA + Cholesky route: data.llt; articulated-body route: data.aba, which
  // also leaves data.liMi and data.oMi)
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd ddq;
  std::vector<AbaBody> aba;
  // trace route (trace_dynamics.hpp)
  std::vector<Mat4> T;              ///< world pose of each body frame as a 4×4 matrix
  std::vector<Mat4> D;              ///< D_i = T_i Δ_i T_i⁻¹: ∂T^(l)/∂q_i = D_i T^(l)
  std::vector<Mat4> H;              ///< pseudo-inertias (copied from the model)
  std::vector<Mat4> Tdd;            ///< Σ_jk T_jk^(l) q̇_j q̇_k per body
  std::vector<Mat4> Td;             ///< Ṫ^(l) per body
  Eigen::MatrixXd M_trace;
  Eigen::VectorXd c_trace, g_trace;
  // points (kinematics.hpp)
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jp; ///< point Jacobian C (3×n)
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jw; ///< angular Jacobian of the point's body (3×n)
};

/// Throws refdyn::Error unless `data` was built for `model` (or a copy of it). The checked
/// algorithms call it; a Data of another model would read and write out of its bounds.
void check_data(const Model& model, const Data& data);

}  // namespace refdyn
