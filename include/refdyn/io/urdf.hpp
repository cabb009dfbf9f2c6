#pragma once
/// URDF loading (with urdfdom) into refdyn's editable ModelDescription.
///
/// Mapping, per URDF joint (parent link -> child link):
///  - <origin xyz rpy>  -> LinkSpec::placement (parent link frame -> joint frame); URDF rpy are
///                         fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
///  - revolute, continuous -> JointType::Revolute; prismatic -> Prismatic; fixed -> Fixed
///                         (build_model folds fixed links into their parent body).
///  - <axis xyz>        -> LinkSpec::axis, normalised (a zero axis is an error).
///  - link_offset is the identity: the URDF child link frame is the joint frame.
///  - <limit lower upper velocity effort> -> JointLimits, taken as written; continuous joints
///                         get no position limits (velocity/effort only).
///  - names: child link name -> LinkSpec::name, joint name -> LinkSpec::joint_name.
/// Per URDF link, <inertial>: com = origin xyz, I_com = R I Rᵀ (R from the origin rpy, I from
/// ixx..izz about the centre of mass in the inertial frame), i.e. expressed in link axes.
/// A link without <inertial> is massless.
///
/// The root link (the URDF's, or UrdfOptions::root_link) becomes a Fixed link attached to the
/// base at the identity, so its frame is the base frame; its mass is welded to the world and
/// does not enter the dynamics. Links are listed parents-first by a depth-first walk from the
/// root; siblings are visited in the natural order of their joint names ("j2" before "j10").
/// This is also the order of the model's coordinates. URDF parts outside the walked subtree
/// are ignored.
///
/// Rotor inertia (Drake's tags, as Drake reads them):
///   <transmission><joint name="J"/><actuator><drake:rotor_inertia value="I_r"/>
///   <drake:gear_ratio value="N"/></actuator></transmission>
/// gives joint J the armature I_r N² (LinkSpec::armature; N = 1 when absent), reported in
/// UrdfExtras::rotors. <visual> elements (mesh, box, cylinder, sphere; the material's colour)
/// become ModelDescription::visuals, a mesh's file resolved as UrdfOptions says. <dynamics
/// damping friction> is not part of the description: it is returned in UrdfExtras::dynamics
/// (scenario files turn it into force elements with model.urdf.dynamics: true). Collision
/// geometry, <calibration>, <safety_controller>, Gazebo tags and the other transmission tags are
/// ignored.
///
/// <mimic joint="L" multiplier="r" offset="c">: the mimicking joint stays a coordinate of its
/// own and the coupling q = r·q_L + c is returned in `mimics` (scenario files turn each into a
/// material joint_coupling constraint named mimic_<joint>). Without `mimics` a <mimic> is an
/// error. The leader must be a movable joint of the loaded subtree.
/// Not supported (refdyn::Error naming the joint): floating and planar joints.
/// A xacro file (a name ending in .xacro, or <xacro:...> elements) is refused with the command
/// that expands it (xacro FILE > FILE.urdf): urdfdom would read it without its macros.
/// Every error is one line: "URDF file '<name>': what is wrong (hint: ...)". urdfdom's own
/// diagnostics are captured (not printed) and quoted in that line; malformed XML is reported
/// with its line number. Any error urdfdom logs is fatal, even when it still returns a model.
/// The result is validated with build_model, so a returned description always builds.

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/model.hpp"

#include <map>
#include <string>
#include <vector>

namespace refdyn::io {

/// A URDF <mimic>: q(joint) = multiplier·q(leader) + offset.
struct UrdfMimic {
  std::string joint, leader;
  double multiplier = 1.0, offset = 0.0;
};

/// A URDF joint's <dynamics damping="b" friction="F">: viscous damping b and Coulomb friction F.
struct UrdfJointDynamics {
  std::string joint;
  double damping = 0.0, friction = 0.0;
};

/// Drake's rotor tags of a joint: armature = rotor_inertia · gear_ratio².
struct UrdfRotor {
  std::string joint;
  double rotor_inertia = 0.0, gear_ratio = 1.0;
  double armature() const { return rotor_inertia * gear_ratio * gear_ratio; }
};

/// What a URDF holds besides the ModelDescription (each in the model's joint order).
struct UrdfExtras {
  std::vector<UrdfMimic> mimics;               ///< <mimic> couplings
  std::vector<UrdfJointDynamics> dynamics;     ///< joints with a non-zero <dynamics> damping or friction
  std::vector<UrdfRotor> rotors;               ///< joints given an armature by Drake's tags
};

struct UrdfOptions {
  /// Link to use as the root (fixed to the base); empty: the URDF's own root link.
  std::string root_link;
  /// package://NAME/PATH of a mesh resolves to FOLDER/PATH for an entry NAME → FOLDER; a package
  /// not listed is looked for in ROS_PACKAGE_PATH (each entry E: E/NAME, or E itself when its
  /// last component is NAME). file:///PATH is PATH; a relative path is taken from the folder of
  /// the URDF file (the source name's folder). A mesh that does not resolve keeps an empty
  /// VisualSpec::file and a note saying why (it is no error: only the report draws meshes).
  std::map<std::string, std::string> packages;
  /// How error messages name the root_link option (scenario files: "model.urdf.root").
  std::string root_link_option = "UrdfOptions::root_link";
  /// Add a named point "<link>" at every link frame origin (so that scenario files can refer
  /// to x(tool)). Links named "world" or "base" that are not the root get no point: refdyn
  /// reserves those point-link names for the world and base frames.
  bool points_for_links = true;
};

/// Thrown when UrdfOptions::root_link is not a link of the URDF (so that a caller can locate the
/// error at the option rather than at the file).
class UrdfRootLinkError : public Error {
 public:
  using Error::Error;
};

/// Reads and parses the URDF file at `path` (error messages name it as given). `mimics`, when
/// given, receives the <mimic> couplings (cleared first).
ModelDescription load_urdf(const std::string& path, const UrdfOptions& opt = {},
                           std::vector<UrdfMimic>* mimics = nullptr);

/// Parses URDF text; `source_name` names it in error messages (e.g. a file name).
ModelDescription parse_urdf(const std::string& xml, const std::string& source_name,
                            const UrdfOptions& opt = {}, std::vector<UrdfMimic>* mimics = nullptr);

/// The same, with everything else the URDF holds in `extras` (overwritten): mimics are accepted.
ModelDescription load_urdf(const std::string& path, const UrdfOptions& opt, UrdfExtras& extras);
ModelDescription parse_urdf(const std::string& xml, const std::string& source_name, const UrdfOptions& opt,
                            UrdfExtras& extras);

}  // namespace refdyn::io
