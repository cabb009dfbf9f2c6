// URDF loading (io/urdf): the example arm, the mapping of origins/axes/inertials/limits checked
// against hand-worked kinematics and mass matrices, a hand-built twin of a 3-DOF URDF arm, the
// order of links, and every error path with its message.
#include "refdyn/io/urdf.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <console_bridge/console.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <unistd.h>

using namespace refdyn;
using refdyn::io::load_urdf;
using refdyn::io::parse_urdf;
using refdyn::io::UrdfOptions;
using refdyn::test::near;

namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

/// examples/urdf/arm7.urdf, found from this file's path (CMake passes absolute source paths).
fs::path arm7_path() { return fs::path(__FILE__).parent_path().parent_path() / "examples" / "urdf" / "arm7.urdf"; }

std::string robot(const std::string& body) { return "<?xml version=\"1.0\"?>\n<robot name=\"t\">\n" + body + "</robot>\n"; }

std::string link(const std::string& name) { return "<link name=\"" + name + "\"/>\n"; }

std::string link(const std::string& name, double mass, const std::string& xyz, const std::string& rpy,
                 double ixx, double iyy, double izz, double ixy = 0, double ixz = 0, double iyz = 0) {
  auto s = [](double x) {
    std::ostringstream os;
    os.precision(17);
    os << x;
    return os.str();
  };
  return "<link name=\"" + name + "\"><inertial><origin xyz=\"" + xyz + "\" rpy=\"" + rpy + "\"/><mass value=\"" +
         s(mass) + "\"/><inertia ixx=\"" + s(ixx) + "\" ixy=\"" + s(ixy) + "\" ixz=\"" + s(ixz) + "\" iyy=\"" +
         s(iyy) + "\" iyz=\"" + s(iyz) + "\" izz=\"" + s(izz) + "\"/></inertial></link>\n";
}

std::string joint(const std::string& name, const std::string& type, const std::string& parent,
                  const std::string& child, const std::string& xyz = "0 0 0", const std::string& rpy = "0 0 0",
                  const std::string& axis = "0 0 1", const std::string& extra = "") {
  std::string limit;
  if (type == "revolute" || type == "prismatic")
    limit = "<limit lower=\"-1\" upper=\"1\" velocity=\"2\" effort=\"3\"/>";
  return "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent + "\"/><child link=\"" + child +
         "\"/><origin xyz=\"" + xyz + "\" rpy=\"" + rpy + "\"/><axis xyz=\"" + axis + "\"/>" + limit + extra +
         "</joint>\n";
}

/// Fixed-axis roll-pitch-yaw, written independently of urdfdom: Rz(y) Ry(p) Rx(r).
Mat3 rpy(double r, double p, double y) {
  return (Eigen::AngleAxisd(y, Vec3::UnitZ()) * Eigen::AngleAxisd(p, Vec3::UnitY()) *
          Eigen::AngleAxisd(r, Vec3::UnitX()))
      .toRotationMatrix();
}

SE3 pose(const Vec3& p, const Mat3& R = Mat3::Identity()) { return {R, p}; }

/// Expects parse_urdf(xml) to throw refdyn::Error, on one line, naming the source and
/// containing every substring.
::testing::AssertionResult fails_with(const std::function<void()>& f, const std::vector<std::string>& parts) {
  try {
    f();
  } catch (const Error& e) {
    const std::string msg = e.what();
    if (msg.find('\n') != std::string::npos)
      return ::testing::AssertionFailure() << "message spans several lines: \"" << msg << "\"";
    for (const auto& p : parts)
      if (msg.find(p) == std::string::npos)
        return ::testing::AssertionFailure() << "message \"" << msg << "\" lacks \"" << p << "\"";
    return ::testing::AssertionSuccess() << msg;
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "threw a non-refdyn exception: " << e.what();
  }
  return ::testing::AssertionFailure() << "did not throw";
}

::testing::AssertionResult parse_fails_with(const std::string& xml, std::vector<std::string> parts,
                                            const UrdfOptions& opt = {}) {
  parts.insert(parts.begin(), "URDF file 'inline.urdf': ");
  return fails_with([&] { parse_urdf(xml, "inline.urdf", opt); }, parts);
}

/// A temporary file removed at scope exit.
struct TempFile {
  fs::path path;
  explicit TempFile(const std::string& content, const std::string& stem = "refdyn_urdf_test") {
    path = fs::temp_directory_path() / (stem + "_" + std::to_string(::getpid()) + ".urdf");
    std::ofstream(path) << content;
  }
  ~TempFile() {
    std::error_code ec;
    fs::remove(path, ec);
  }
};

Vec3 point_at(const Model& m, const Eigen::VectorXd& q, const std::string& point) {
  Data data(m);
  forward_kinematics(m, data, q);
  return point_position(m, data, m.point_index(point));
}

Eigen::MatrixXd mass_matrix_at(const Model& m, const Eigen::VectorXd& q) {
  Data data(m);
  return mass_matrix(m, data, q);
}

}  // namespace

// --- the example arm ---------------------------------------------------------------------------

TEST(UrdfArm7, LoadsFromFileWithNamesLimitsAndPoints) {
  ASSERT_TRUE(fs::exists(arm7_path())) << arm7_path();
  const ModelDescription d = load_urdf(arm7_path().string());
  EXPECT_EQ(d.name, "arm7");
  ASSERT_EQ(d.links.size(), 9u);  // base_link (fixed to the base), link1..link7, tool (fixed)
  EXPECT_EQ(d.links[0].name, "base_link");
  EXPECT_EQ(d.links[0].parent, -1);
  EXPECT_EQ(d.links[0].type, JointType::Fixed);
  for (int i = 1; i <= 7; ++i) {
    const LinkSpec& l = d.links[i];
    EXPECT_EQ(l.name, "link" + std::to_string(i));
    EXPECT_EQ(l.joint_name, "j" + std::to_string(i));
    EXPECT_EQ(l.parent, i - 1);
    EXPECT_EQ(l.type, JointType::Revolute);
    EXPECT_TRUE(near(l.axis, Vec3::UnitZ(), 0, 1e-15));
    EXPECT_TRUE(l.link_offset.R.isIdentity(0) && l.link_offset.p.isZero(0));
  }
  EXPECT_EQ(d.links[8].name, "tool");
  EXPECT_EQ(d.links[8].joint_name, "tool_joint");
  EXPECT_EQ(d.links[8].type, JointType::Fixed);
  EXPECT_DOUBLE_EQ(d.links[1].limits.lower, -2.967060);
  EXPECT_DOUBLE_EQ(d.links[1].limits.upper, 2.967060);
  EXPECT_DOUBLE_EQ(d.links[1].limits.velocity, 1.71);
  EXPECT_DOUBLE_EQ(d.links[1].limits.effort, 100);
  EXPECT_DOUBLE_EQ(d.links[7].limits.upper, 3.054326);
  EXPECT_DOUBLE_EQ(d.links[7].limits.effort, 10);
  // joint 2's origin: 0.2 m up, rpy (-π/2, 0, 0)
  EXPECT_TRUE(near(d.links[2].placement.p, Vec3(0, 0, 0.2), 0, 1e-15));
  EXPECT_TRUE(near(d.links[2].placement.R, rpy(-kPi / 2, 0, 0), 0, 1e-15));
  // link 2's inertia: given along z, turned onto y by the inertial rpy (π/2, 0, 0)
  EXPECT_TRUE(near(d.links[2].inertia.I_com, Vec3(0.0127, 0.0054, 0.0127).asDiagonal().toDenseMatrix(), 0, 1e-15));
  EXPECT_TRUE(near(d.links[2].inertia.com, Vec3(0, -0.1, 0), 0, 0));
  // one point per link
  ASSERT_EQ(d.points.size(), 9u);
  EXPECT_EQ(d.points.back().name, "tool");
  EXPECT_EQ(d.points.back().link, "tool");

  const Model m = build_model(d);
  EXPECT_EQ(m.nq, 7);
  EXPECT_EQ(m.joint_index("j7"), 6);
  EXPECT_NEAR(m.total_mass(), 3.5 + 3.0 + 2.5 + 2.0 + 1.5 + 1.0 + 0.5 + 0.4, 1e-12);  // base_link is welded
  // straight up at q = 0: 0.15 + 0.2 + 0.2 + 0.2 + 0.2 + 0.2 + 0.08 + 0.16
  EXPECT_TRUE(near(point_at(m, Eigen::VectorXd::Zero(7), "tool"), Vec3(0, 0, 1.39), 0, 1e-12));
  // j2's axis is link1's y (rpy (-π/2,0,0) takes z onto y): j2 = π/2 tips the arm above j2
  // (1.39 - 0.35 = 1.04 m) over onto +x; j1 = π/2 then turns it onto +y.
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  q[1] = kPi / 2;
  EXPECT_TRUE(near(point_at(m, q, "tool"), Vec3(1.04, 0, 0.35), 0, 1e-12));
  q[0] = kPi / 2;
  EXPECT_TRUE(near(point_at(m, q, "tool"), Vec3(0, 1.04, 0.35), 0, 1e-12));
  // and everywhere the reference kinematics of the description agree
  std::mt19937 rng(7);
  for (int k = 0; k < 5; ++k) {
    Eigen::VectorXd qr = test::random_vector(rng, 7, 2.0);
    EXPECT_TRUE(near(point_at(m, qr, "tool"), test::reference_point_position(d, qr, "tool"), 0, 1e-12));
  }
}

TEST(UrdfArm7, MassMatrixIsSymmetricPositiveDefinite) {
  const Model m = build_model(load_urdf(arm7_path().string()));
  std::mt19937 rng(3);
  for (int k = 0; k < 5; ++k) {
    Eigen::MatrixXd M = mass_matrix_at(m, test::random_vector(rng, 7, 2.0));
    EXPECT_TRUE(near(M, M.transpose(), 0, 1e-14));
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(M).info(), Eigen::Success);
  }
}

// --- mapping, hand-worked --------------------------------------------------------------------

TEST(UrdfMapping, TwoLinkPlanarKinematics) {
  // j1 about z at the origin, j2 about z 1 m along link1's x, the tip 1 m along link2's x.
  const std::string xml = robot(link("ground") + link("link1") + link("link2") + link("tip") +
                                joint("j1", "revolute", "ground", "link1") +
                                joint("j2", "revolute", "link1", "link2", "1 0 0") +
                                joint("tip_joint", "fixed", "link2", "tip", "1 0 0"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  const Model m = build_model(d);
  ASSERT_EQ(m.nq, 2);
  for (double q1 : {0.0, 0.3, -1.2})
    for (double q2 : {0.0, 0.7, 2.5}) {
      Eigen::VectorXd q(2);
      q << q1, q2;
      const Vec3 expected(std::cos(q1) + std::cos(q1 + q2), std::sin(q1) + std::sin(q1 + q2), 0);
      EXPECT_TRUE(near(point_at(m, q, "tip"), expected, 0, 1e-14)) << q.transpose();
      EXPECT_TRUE(near(point_at(m, q, "link2"), Vec3(std::cos(q1), std::sin(q1), 0), 0, 1e-14));
    }
}

TEST(UrdfMapping, JointOriginRpyIsFixedAxisRollPitchYaw) {
  const std::string xml =
      robot(link("a") + link("b") + joint("j", "revolute", "a", "b", "0.1 -0.2 0.3", "0.4 -0.5 0.6", "1 2 2"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  ASSERT_EQ(d.links.size(), 2u);
  EXPECT_TRUE(near(d.links[1].placement.R, rpy(0.4, -0.5, 0.6), 0, 1e-15));
  EXPECT_TRUE(near(d.links[1].placement.p, Vec3(0.1, -0.2, 0.3), 0, 0));
  EXPECT_TRUE(near(d.links[1].axis, Vec3(1, 2, 2) / 3.0, 0, 1e-16));  // normalised
}

TEST(UrdfMapping, InertialRpyRotatesTheInertia) {
  // Revolute about z at the origin; COM 0.5 m along x; the inertial frame is rolled by π/2
  // about x, so the inertial frame's y axis is the link's z axis: I_zz(link) = iyy.
  const double m = 2.0, dx = 0.5, ixx = 0.2, iyy = 0.3, izz = 0.15;
  const std::string xml = robot(link("a") + link("b", m, "0.5 0 0", "1.5707963267948966 0 0", ixx, iyy, izz) +
                                joint("j", "revolute", "a", "b"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  EXPECT_TRUE(near(d.links[1].inertia.I_com, Vec3(ixx, izz, iyy).asDiagonal().toDenseMatrix(), 0, 1e-15));
  const Model model = build_model(d);
  const Eigen::MatrixXd M = mass_matrix_at(model, Eigen::VectorXd::Constant(1, 0.4));
  EXPECT_NEAR(M(0, 0), m * dx * dx + iyy, 1e-14);  // m d² + I_axis

  // A general rpy and a full tensor: I_com = R I Rᵀ.
  Mat3 I;
  I << 0.3, 0.01, -0.02, 0.01, 0.4, 0.03, -0.02, 0.03, 0.5;
  const std::string xml2 = robot(link("a") + link("b", 1.5, "0.1 0.2 0.3", "0.7 -0.3 1.1", I(0, 0), I(1, 1), I(2, 2),
                                                   I(0, 1), I(0, 2), I(1, 2)) +
                                 joint("j", "revolute", "a", "b"));
  const ModelDescription d2 = parse_urdf(xml2, "inline.urdf");
  const Mat3 R = rpy(0.7, -0.3, 1.1);
  EXPECT_TRUE(near(d2.links[1].inertia.I_com, R * I * R.transpose(), 0, 1e-15));
  EXPECT_TRUE(near(d2.links[1].inertia.com, Vec3(0.1, 0.2, 0.3), 0, 0));
  EXPECT_DOUBLE_EQ(d2.links[1].inertia.mass, 1.5);
}

TEST(UrdfMapping, FixedJointChildMassIsMerged) {
  // l1: 1 kg at 0.2 m, izz 0.01; a fixed 0.5 m extension carrying l2: 2 kg at a further
  // (0.1, 0.1, 0), izz 0.02. One coordinate; M = Σ m r⊥² + Σ izz; total mass kept.
  const std::string xml = robot(link("a") + link("l1", 1.0, "0.2 0 0", "0 0 0", 0.01, 0.01, 0.01) +
                                link("l2", 2.0, "0.1 0.1 0", "0 0 0", 0.02, 0.02, 0.02) +
                                joint("j1", "revolute", "a", "l1") + joint("weld", "fixed", "l1", "l2", "0.5 0 0"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  const Model m = build_model(d);
  ASSERT_EQ(m.nq, 1);
  EXPECT_NEAR(m.total_mass(), 3.0, 1e-15);
  const double expected = 1.0 * 0.04 + 0.01 + 2.0 * (0.6 * 0.6 + 0.1 * 0.1) + 0.02;
  EXPECT_NEAR(mass_matrix_at(m, Eigen::VectorXd::Constant(1, -0.9))(0, 0), expected, 1e-14);
  // the point of the fixed link moves with l1
  EXPECT_TRUE(near(point_at(m, Eigen::VectorXd::Constant(1, kPi / 2), "l2"), Vec3(0, 0.5, 0), 0, 1e-15));
}

TEST(UrdfMapping, JointTypesAndLimits) {
  const std::string xml =
      robot(link("a") + link("b") + link("c") + link("d") + link("e") + link("f") +
            joint("j1", "continuous", "a", "b", "0 0 0", "0 0 0", "0 0 1",
                  "<limit effort=\"7\" velocity=\"5\"/>") +
            joint("j2", "prismatic", "b", "c", "0 0 0", "0 0 0", "0 0 -2") +
            joint("j3", "continuous", "c", "d") +              // no <limit>: unlimited
            joint("j4", "revolute", "d", "e", "0 0 0", "0 0 0", "1 0 0") +
            joint("j5", "fixed", "e", "f"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  ASSERT_EQ(d.links.size(), 6u);
  const auto inf = std::numeric_limits<double>::infinity();
  const LinkSpec &j1 = d.links[1], &j2 = d.links[2], &j3 = d.links[3], &j4 = d.links[4], &j5 = d.links[5];
  EXPECT_EQ(j1.type, JointType::Revolute);
  EXPECT_EQ(j1.limits.lower, -inf);
  EXPECT_EQ(j1.limits.upper, inf);
  EXPECT_EQ(j1.limits.velocity, 5);
  EXPECT_EQ(j1.limits.effort, 7);
  EXPECT_EQ(j2.type, JointType::Prismatic);
  EXPECT_TRUE(near(j2.axis, Vec3(0, 0, -1), 0, 0));
  EXPECT_EQ(j2.limits.lower, -1);
  EXPECT_EQ(j2.limits.upper, 1);
  EXPECT_EQ(j2.limits.velocity, 2);
  EXPECT_EQ(j2.limits.effort, 3);
  EXPECT_EQ(j3.type, JointType::Revolute);
  EXPECT_EQ(j3.limits.lower, -inf);
  EXPECT_EQ(j3.limits.velocity, inf);
  EXPECT_EQ(j4.type, JointType::Revolute);
  EXPECT_TRUE(near(j4.axis, Vec3::UnitX(), 0, 0));
  EXPECT_EQ(j5.type, JointType::Fixed);
  EXPECT_EQ(j5.joint_name, "j5");
  // a link without <inertial> is massless
  EXPECT_EQ(j4.inertia.mass, 0.0);
  EXPECT_TRUE(j4.inertia.I_com.isZero(0));
  // the prismatic joint moves along -z
  const Model m = build_model(d);
  ASSERT_EQ(m.nq, 4);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(4);
  q[1] = 0.25;
  EXPECT_TRUE(near(point_at(m, q, "f"), Vec3(0, 0, -0.25), 0, 1e-15));
}

TEST(UrdfMapping, LinksAreOrderedParentsFirstWithSiblingsInNaturalOrder) {
  // Listed children-first in the file; a branch at the root: j10 -> a, j2 -> b -> j3 -> c.
  const std::string xml =
      robot(joint("j3", "revolute", "b", "c") + link("c") + joint("j10", "revolute", "torso", "a") + link("a") +
            joint("j2", "revolute", "torso", "b") + link("b") + link("torso"));
  const ModelDescription d = parse_urdf(xml, "inline.urdf");
  std::vector<std::string> names;
  for (const auto& l : d.links) names.push_back(l.name);
  EXPECT_EQ(names, (std::vector<std::string>{"torso", "b", "c", "a"}));
  for (size_t i = 0; i < d.links.size(); ++i) EXPECT_LT(d.links[i].parent, static_cast<int>(i));
  EXPECT_EQ(d.links[2].parent, 1);
  EXPECT_EQ(d.links[3].parent, 0);
  const Model m = build_model(d);
  EXPECT_EQ(m.joint_name, (std::vector<std::string>{"j2", "j3", "j10"}));
}

TEST(UrdfMapping, RootLinkOptionAndPointsOption) {
  const std::string xml =
      robot(link("world") + link("base_link") + link("l1", 1.0, "0 0 0.1", "0 0 0", 0.01, 0.01, 0.01) +
            link("l2", 1.0, "0 0 0.1", "0 0 0", 0.01, 0.01, 0.01) + link("base") +
            joint("float", "floating", "world", "base_link") + joint("j1", "revolute", "base_link", "l1", "0 0 0.5") +
            joint("j2", "revolute", "l1", "l2", "0 0 0.4", "0 0 0", "0 1 0") +
            joint("b_fixed", "fixed", "base_link", "base"));
  // The floating joint is outside the subtree of base_link: not an error.
  UrdfOptions opt;
  opt.root_link = "base_link";
  const ModelDescription d = parse_urdf(xml, "inline.urdf", opt);
  ASSERT_EQ(d.links.size(), 4u);  // base_link, base (fixed), l1, l2
  EXPECT_EQ(d.links[0].name, "base_link");
  const Model m = build_model(d);
  EXPECT_EQ(m.nq, 2);
  // A non-root link named "base" gets no point ("base" means refdyn's base frame).
  std::vector<std::string> points;
  for (const auto& p : d.points) points.push_back(p.name);
  EXPECT_EQ(points, (std::vector<std::string>{"base_link", "l1", "l2"}));
  EXPECT_TRUE(near(point_at(m, Eigen::VectorXd::Zero(2), "l2"), Vec3(0, 0, 0.9), 0, 1e-15));

  // Rooted deeper: l1 is welded to the base, one coordinate left.
  opt.root_link = "l1";
  opt.points_for_links = false;
  const ModelDescription d1 = parse_urdf(xml, "inline.urdf", opt);
  ASSERT_EQ(d1.links.size(), 2u);
  EXPECT_TRUE(d1.points.empty());
  EXPECT_EQ(build_model(d1).nq, 1);

  // A URDF root named "world" keeps its point (it is the world frame anyway).
  const ModelDescription dw =
      parse_urdf(robot(link("world") + link("arm") + joint("j", "revolute", "world", "arm", "0 0 1")), "inline.urdf");
  EXPECT_EQ(dw.points.size(), 2u);
  EXPECT_TRUE(near(point_at(build_model(dw), Eigen::VectorXd::Zero(1), "arm"), Vec3(0, 0, 1), 0, 0));
}

// --- a URDF arm and its hand-built twin -------------------------------------------------------

TEST(UrdfCrossCheck, ThreeDofArmEqualsHandBuiltDescription) {
  // URDF side
  Mat3 I3;
  I3 << 0.02, 0.001, -0.002, 0.001, 0.03, 0.0015, -0.002, 0.0015, 0.025;
  const std::string xml =
      robot(link("base_link", 4.0, "0 0 0.05", "0 0 0", 0.02, 0.02, 0.02) +
            link("l1", 2.0, "0 0 0.1", "0 0 0", 0.02, 0.02, 0.01) +
            link("l2", 1.5, "0.2 0 0", "0 0.4 0", 0.004, 0.03, 0.03) +
            link("l3", 1.0, "0.05 0.02 0.1", "0.3 -0.2 0.5", I3(0, 0), I3(1, 1), I3(2, 2), I3(0, 1), I3(0, 2),
                 I3(1, 2)) +
            joint("j1", "revolute", "base_link", "l1", "0 0 0.3") +
            joint("j2", "revolute", "l1", "l2", "0.05 0 0.2", "-1.5707963267948966 0 0") +
            joint("j3", "revolute", "l2", "l3", "0.4 0 0", "0.3 -0.2 0.5", "0 1 1"));
  const ModelDescription du = parse_urdf(xml, "inline.urdf");

  // Hand side: the same numbers through LinkSpec placements.
  ModelDescription dh;
  LinkSpec l1, l2, l3;
  l1.name = "l1";
  l1.parent = -1;
  l1.placement = pose(Vec3(0, 0, 0.3));
  l1.inertia = {2.0, Vec3(0, 0, 0.1), Vec3(0.02, 0.02, 0.01).asDiagonal()};
  l2.name = "l2";
  l2.parent = 0;
  l2.placement = pose(Vec3(0.05, 0, 0.2), Eigen::AngleAxisd(-kPi / 2, Vec3::UnitX()).toRotationMatrix());
  const Mat3 R2 = Eigen::AngleAxisd(0.4, Vec3::UnitY()).toRotationMatrix();
  l2.inertia = {1.5, Vec3(0.2, 0, 0), R2 * Vec3(0.004, 0.03, 0.03).asDiagonal() * R2.transpose()};
  l3.name = "l3";
  l3.parent = 1;
  l3.placement = pose(Vec3(0.4, 0, 0), rpy(0.3, -0.2, 0.5));
  l3.axis = Vec3(0, 1, 1) / std::sqrt(2.0);
  const Mat3 R3 = rpy(0.3, -0.2, 0.5);
  l3.inertia = {1.0, Vec3(0.05, 0.02, 0.1), R3 * I3 * R3.transpose()};
  dh.add_link(l1);
  dh.add_link(l2);
  dh.add_link(l3);
  dh.add_point("l3", "l3", Vec3::Zero());

  const Model mu = build_model(du), mh = build_model(dh);
  ASSERT_EQ(mu.nq, 3);
  ASSERT_EQ(mh.nq, 3);
  EXPECT_NEAR(mu.total_mass(), mh.total_mass(), 1e-15);
  std::mt19937 rng(11);
  for (int k = 0; k < 6; ++k) {
    const Eigen::VectorXd q = test::random_vector(rng, 3, 2.5);
    EXPECT_TRUE(near(mass_matrix_at(mu, q), mass_matrix_at(mh, q), 1e-13, 1e-15)) << q.transpose();
    Data du_data(mu), dh_data(mh);
    EXPECT_TRUE(near(gravity_forces(mu, du_data, q), gravity_forces(mh, dh_data, q), 1e-13, 1e-14));
    EXPECT_TRUE(near(point_at(mu, q, "l3"), point_at(mh, q, "l3"), 0, 1e-15));
  }
}

// --- files -------------------------------------------------------------------------------------

TEST(UrdfFiles, TemporaryFileLoadsAndErrorsNameIt) {
  TempFile ok(robot(link("a") + link("b", 1.0, "0 0 0", "0 0 0", 0.1, 0.1, 0.1) + joint("j", "revolute", "a", "b")));
  const ModelDescription d = load_urdf(ok.path.string());
  EXPECT_EQ(d.links.size(), 2u);
  EXPECT_EQ(d.name, "t");

  TempFile bad("<robot name=\"t\">\n  <link name=\"a\">\n  <link name=\"b\"/>\n</robot>\n", "refdyn_urdf_bad");
  EXPECT_TRUE(fails_with([&] { load_urdf(bad.path.string()); },
                         {"URDF file '" + bad.path.string() + "': ", "not well-formed XML at line 4, column ", "closing tag"}));
}

// --- errors ------------------------------------------------------------------------------------

TEST(UrdfErrors, MissingFileAndDirectory) {
  EXPECT_TRUE(fails_with([] { load_urdf("/nonexistent/x.urdf"); },
                         {"URDF file '/nonexistent/x.urdf': cannot be read: No such file or directory", "hint"}));
  const std::string dir = fs::temp_directory_path().string();
  EXPECT_TRUE(fails_with([&] { load_urdf(dir); }, {"URDF file '" + dir + "': cannot be read", "directory"}));
}

TEST(UrdfErrors, MalformedXmlHasALineNumber) {
  EXPECT_TRUE(parse_fails_with("<robot name=\"t\">\n<link name=\"a\">\n\n</robot>\n",
                               {"not well-formed XML at line 4, column ", "hint"}));
  EXPECT_TRUE(parse_fails_with("<robot name=\"t\">\n  <link name=\"a\"/>\n  <link name=\"b\" mass=1/>\n</robot>",
                               {"not well-formed XML at line 3, column "}));
  EXPECT_TRUE(parse_fails_with("this is not xml", {"not well-formed XML at line 1, column 1"}));
  EXPECT_TRUE(parse_fails_with("", {"is empty", "hint"}));
  EXPECT_TRUE(parse_fails_with(" \n ", {"is empty"}));
}

TEST(UrdfErrors, InvalidUrdfQuotesUrdfdom) {
  EXPECT_TRUE(parse_fails_with("<model/>", {"not a valid URDF", "robot", "hint"}));
  // revolute without <limit>
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") +
                                     "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>"
                                     "</joint>"),
                               {"not a valid URDF", "Joint [j]", "limits"}));
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") + joint("j", "weird", "a", "b")),
                               {"not a valid URDF", "weird"}));
  // two roots
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b")), {"not a valid URDF", "root"}));
  // <inertial> without <inertia>: urdfdom logs an error but returns a model; still rejected
  EXPECT_TRUE(parse_fails_with(
      robot("<link name=\"a\"><inertial><mass value=\"1\"/></inertial></link>"), {"not a valid URDF", "inertia"}));
  // a malformed number
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") + joint("j", "fixed", "a", "b", "1 x 2")),
                               {"not a valid URDF", "[x]"}));
}

TEST(UrdfErrors, UrdfdomDiagnosticsAreCapturedNotPrinted) {
  // A handler installed by the application keeps working, and sees none of the parse errors.
  struct Collect : console_bridge::OutputHandler {
    std::vector<std::string> seen;
    void log(const std::string& text, console_bridge::LogLevel, const char*, int) override { seen.push_back(text); }
  } mine;
  console_bridge::useOutputHandler(&mine);
  testing::internal::CaptureStderr();
  EXPECT_THROW(parse_urdf(robot(link("a") + link("b") + joint("j", "weird", "a", "b")), "x.urdf"), Error);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "");
  EXPECT_TRUE(mine.seen.empty());
  CONSOLE_BRIDGE_logError("after the parse");
  ASSERT_EQ(mine.seen.size(), 1u);
  EXPECT_EQ(mine.seen[0], "after the parse");
  console_bridge::restorePreviousOutputHandler();
}

TEST(UrdfErrors, UnsupportedJoints) {
  EXPECT_TRUE(parse_fails_with(robot(link("world") + link("base_link") + joint("free", "floating", "world", "base_link")),
                               {"joint 'free' is floating", "not supported", "set UrdfOptions::root_link to 'base_link'"}));
  // A caller that exposes the option under another name (scenario files: model.urdf.root) gets
  // that name in the hint, never the C++ one.
  UrdfOptions scenario;
  scenario.root_link_option = "model.urdf.root";
  try {
    parse_urdf(robot(link("world") + link("base_link") + joint("free", "floating", "world", "base_link")), "inline.urdf",
               scenario);
    ADD_FAILURE() << "a floating joint was accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("set model.urdf.root to 'base_link'"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("UrdfOptions"), std::string::npos) << msg;
  }
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") + joint("slide", "planar", "a", "b")),
                               {"joint 'slide' is planar", "not supported", "hint"}));
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") + link("c") + joint("j1", "revolute", "a", "b") +
                                     joint("j2", "revolute", "b", "c", "0 0 0", "0 0 0", "0 0 1",
                                           "<mimic joint=\"j1\" multiplier=\"2\"/>")),
                               {"joint 'j2' mimics joint 'j1'", "not asked for mimic couplings", "hint"}));
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") + joint("j", "continuous", "a", "b", "0 0 0", "0 0 0", "0 0 0")),
                               {"joint 'j'", "axis is zero", "hint"}));
}

// <mimic>: the joint stays a coordinate and the coupling is returned for a joint_coupling
// constraint; the leader must be a movable joint of the loaded model.
TEST(UrdfMapping, MimicJointsAreReturnedAsCouplings) {
  const std::string body = link("a") + link("b", 1.0, "0.1 0 0", "0 0 0", 0.01, 0.01, 0.01) +
                           link("c", 1.0, "0.1 0 0", "0 0 0", 0.01, 0.01, 0.01) + joint("j1", "revolute", "a", "b") +
                           joint("j2", "revolute", "b", "c", "0.2 0 0", "0 0 0", "0 0 1",
                                 "<mimic joint=\"j1\" multiplier=\"-2.5\" offset=\"0.3\"/>");
  std::vector<io::UrdfMimic> mimics{{"stale", "entry", 9, 9}};
  const ModelDescription d = parse_urdf(robot(body), "inline.urdf", {}, &mimics);
  ASSERT_EQ(mimics.size(), 1u);
  EXPECT_EQ(mimics[0].joint, "j2");
  EXPECT_EQ(mimics[0].leader, "j1");
  EXPECT_EQ(mimics[0].multiplier, -2.5);
  EXPECT_EQ(mimics[0].offset, 0.3);
  EXPECT_EQ(build_model(d).nq, 2);  // the mimicking joint keeps its coordinate
  // Leader fixed, or not in the loaded model.
  const std::string fixed_leader = link("a") + link("b", 1.0, "0 0 0", "0 0 0", 0.01, 0.01, 0.01) +
                                   link("c", 1.0, "0 0 0", "0 0 0", 0.01, 0.01, 0.01) + joint("j1", "fixed", "a", "b") +
                                   joint("j2", "revolute", "b", "c", "0 0 0", "0 0 0", "0 0 1",
                                         "<mimic joint=\"j1\" multiplier=\"2\"/>");
  EXPECT_TRUE(fails_with([&] { parse_urdf(robot(fixed_leader), "inline.urdf", {}, &mimics); },
                         {"joint 'j2' mimics 'j1'", "a fixed joint", "hint"}));
  UrdfOptions below;
  below.root_link = "b";
  EXPECT_TRUE(fails_with([&] { parse_urdf(robot(body), "inline.urdf", below, &mimics); },
                         {"joint 'j2' mimics 'j1'", "not a joint of the loaded model"}));
}

TEST(UrdfErrors, PhysicalValidationNamesTheFile) {
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("l1", -1.0, "0 0 0", "0 0 0", 0.1, 0.1, 0.1) +
                                     joint("j", "revolute", "a", "l1")),
                               {"link 'l1' mass", "-1", "hint"}));
  // triangle inequality
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("l1", 1.0, "0 0 0", "0 0 0", 0.1, 0.1, 0.5) +
                                     joint("j", "revolute", "a", "l1")),
                               {"link 'l1' principal moments of inertia", "triangle"}));
  EXPECT_TRUE(parse_fails_with(robot(link("a") + link("b") +
                                     "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>"
                                     "<limit lower=\"1\" upper=\"-1\" effort=\"1\" velocity=\"1\"/></joint>"),
                               {"('b') position limits", "lower <= upper"}));
}

TEST(UrdfErrors, UnknownRootLink) {
  UrdfOptions opt;
  opt.root_link = "lnk1";
  EXPECT_TRUE(parse_fails_with(robot(link("base_link") + link("link1") + joint("j1", "revolute", "base_link", "link1")),
                               {"root link 'lnk1' is not a link of this URDF", "did you mean 'link1'"}, opt));
  // Its own type, so that a scenario reports it under model.urdf.root rather than the file.
  EXPECT_THROW(parse_urdf(robot(link("base_link") + link("link1") + joint("j1", "revolute", "base_link", "link1")),
                          "inline.urdf", opt),
               io::UrdfRootLinkError);
  // Another error of the same file is not a root-link error.
  try {
    parse_urdf(robot(link("a") + link("b") + joint("slide", "planar", "a", "b")), "inline.urdf");
    ADD_FAILURE() << "a planar joint was accepted";
  } catch (const io::UrdfRootLinkError& e) {
    ADD_FAILURE() << "a planar joint reported as a root-link error: " << e.what();
  } catch (const Error&) {
  }
}

// A xacro file is not a URDF: urdfdom reads it without its macros ("No name given for the robot",
// or a model missing the links its macros make). It is refused with the command that expands it,
// whether recognised by a <xacro:...> element or by its name.
TEST(UrdfErrors, XacroFilesAreRefusedWithTheExpandCommand) {
  const std::string body = link("base_link") + "<xacro:macro name=\"arm\" params=\"n\"><link name=\"${n}\"/></xacro:macro>\n" +
                           "<xacro:arm n=\"link1\"/>\n" + joint("j1", "revolute", "base_link", "link1");
  const std::string xacro = "<?xml version=\"1.0\"?>\n<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n" + body +
                            "</robot>\n";
  EXPECT_TRUE(parse_fails_with(xacro, {"this is a xacro file", "<xacro:...> elements",
                                       "expand it first with `xacro inline.urdf > inline.urdf.urdf`"}));
  // By name: arm.urdf.xacro expands to arm.urdf, arm.xacro to arm.urdf.
  EXPECT_TRUE(fails_with([&] { parse_urdf(xacro, "robots/arm.urdf.xacro"); },
                         {"URDF file 'robots/arm.urdf.xacro': this is a xacro file", "its name ends in .xacro",
                          "`xacro robots/arm.urdf.xacro > robots/arm.urdf`", "load robots/arm.urdf"}));
  EXPECT_TRUE(fails_with([&] { parse_urdf(robot(link("a")), "arm.xacro"); }, {"`xacro arm.xacro > arm.urdf`"}));
  // An expanded file may keep the xmlns:xacro declaration: without <xacro:...> elements it is a URDF.
  const std::string expanded = "<?xml version=\"1.0\"?>\n<robot name=\"t\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n" +
                               link("a") + link("b", 1.0, "0 0 0", "0 0 0", 0.1, 0.1, 0.1) +
                               joint("j", "revolute", "a", "b") + "</robot>\n";
  EXPECT_EQ(build_model(parse_urdf(expanded, "expanded.urdf")).nq, 1);
}

// --- the test robots of tests/data/urdf/refdyn_test_arm (a description package) --------------

namespace {
fs::path test_arm_package() { return fs::path(REFDYN_SOURCE_DIR) / "tests" / "data" / "urdf" / "refdyn_test_arm"; }
}  // namespace

// Drake's rotor tags give the armature I_r N² (as Drake's reflected inertia); <dynamics> is
// returned, not applied; the mimic finger is a coupling; rounded π in the joint origins.
TEST(UrdfTestArm, DrakeRotorTagsDynamicsAndMimic) {
  io::UrdfExtras ex;
  const ModelDescription d = load_urdf((test_arm_package() / "urdf" / "arm7_hand.urdf").string(), {}, ex);
  const Model m = build_model(d);
  ASSERT_EQ(m.nq, 9);  // joint1..7, two fingers; world, flange, hand and tcp folded
  ASSERT_EQ(ex.rotors.size(), 7u);
  for (int j = 0; j < 7; ++j) {
    const double I_r = j < 4 ? 0.000335 : 0.000116;
    EXPECT_EQ(ex.rotors[j].joint, "joint" + std::to_string(j + 1));
    EXPECT_DOUBLE_EQ(ex.rotors[j].gear_ratio, 100.0);
    EXPECT_DOUBLE_EQ(m.armature[m.joint_index("joint" + std::to_string(j + 1))], I_r * 100 * 100);
  }
  EXPECT_EQ(m.armature[m.joint_index("finger_joint1")], 0.0);
  ASSERT_EQ(ex.dynamics.size(), 7u);  // the fingers have none
  EXPECT_EQ(ex.dynamics[0].joint, "joint1");
  EXPECT_DOUBLE_EQ(ex.dynamics[0].damping, 0.5);
  EXPECT_DOUBLE_EQ(ex.dynamics[6].friction, 0.1);
  ASSERT_EQ(ex.mimics.size(), 1u);
  EXPECT_EQ(ex.mimics[0].joint, "finger_joint2");
  EXPECT_EQ(ex.mimics[0].leader, "finger_joint1");
  // continuous joint7: speed and effort limits, no position limits
  const JointLimits& l7 = m.limits[m.joint_index("joint7")];
  EXPECT_TRUE(std::isinf(l7.lower) && std::isinf(l7.upper));
  EXPECT_EQ(l7.effort, 40.0);
  // standing straight up at q = 0: the tool point on the z axis, rounded π leaving ~1e-12
  const Vec3 tcp = point_at(m, Eigen::VectorXd::Zero(9), "tcp");
  EXPECT_NEAR(tcp.x(), 0.0, 1e-10);
  EXPECT_NEAR(tcp.y(), 0.0, 1e-10);
  EXPECT_NEAR(tcp.z(), 0.16 + 0.2 + 0.21 + 0.19 + 0.2 + 0.21 + 0.085 + 0.045 + 0.105, 1e-10);
  // M's diagonal carries the armature: the same model with the tags removed has it less
  ModelDescription bare = d;
  for (LinkSpec& l : bare.links) l.armature = 0;
  const Eigen::VectorXd q = (Eigen::VectorXd(9) << 0.2, 0.5, 0, -1.2, 0, 0.9, 0, 0.01, 0.01).finished();
  const Eigen::MatrixXd dM = mass_matrix_at(m, q) - mass_matrix_at(build_model(bare), q);
  const Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(m.armature.data(), 9);
  EXPECT_TRUE(near(dM, Eigen::MatrixXd(a.asDiagonal()), 1e-14, 1e-14));
}

TEST(UrdfTestArm, VisualsResolvePackagesRosPackagePathAndRelativePaths) {
  const std::string urdf = (test_arm_package() / "urdf" / "arm7_hand.urdf").string();
  UrdfOptions opt;
  opt.packages["refdyn_test_arm"] = test_arm_package().string();
  io::UrdfExtras ex;  // (the mimic finger wants its coupling returned)
  const ModelDescription d = load_urdf(urdf, opt, ex);
  int meshes = 0, boxes = 0, spheres = 0;
  for (const VisualSpec& v : d.visuals) {
    if (v.shape == VisualSpec::Shape::Mesh) {
      ++meshes;
      EXPECT_TRUE(fs::exists(v.file)) << v.uri << " -> " << v.file;
      EXPECT_TRUE(v.note.empty()) << v.note;
    }
    boxes += v.shape == VisualSpec::Shape::Box;
    spheres += v.shape == VisualSpec::Shape::Sphere;
  }
  EXPECT_EQ(meshes, 11);
  EXPECT_EQ(boxes, 1);
  EXPECT_EQ(spheres, 1);
  EXPECT_EQ(d.visuals.front().link, "base_link");
  EXPECT_TRUE(d.visuals.front().has_color);  // the global material "grey"
  EXPECT_NEAR(d.visuals.front().rgba[0], 0.55, 1e-6);  // urdfdom keeps colours as float
  // Unknown package: no error, a note on each mesh.
  struct RestoreEnv {
    std::string old;
    bool had;
    RestoreEnv() : had(std::getenv("ROS_PACKAGE_PATH") != nullptr) { if (had) old = std::getenv("ROS_PACKAGE_PATH"); }
    ~RestoreEnv() { had ? ::setenv("ROS_PACKAGE_PATH", old.c_str(), 1) : ::unsetenv("ROS_PACKAGE_PATH"); }
  } restore;
  ::unsetenv("ROS_PACKAGE_PATH");
  const ModelDescription u = load_urdf(urdf, {}, ex);
  for (const VisualSpec& v : u.visuals)
    if (v.shape == VisualSpec::Shape::Mesh) {
      EXPECT_TRUE(v.file.empty());
      EXPECT_NE(v.note.find("package 'refdyn_test_arm' is not known"), std::string::npos) << v.note;
    }
  // ROS_PACKAGE_PATH: an entry holding the package folder, or the package folder itself.
  for (const fs::path& entry : {test_arm_package().parent_path(), test_arm_package()}) {
    ::setenv("ROS_PACKAGE_PATH", ("/nonexistent:" + entry.string()).c_str(), 1);
    const ModelDescription r = load_urdf(urdf, {}, ex);
    for (const VisualSpec& v : r.visuals)
      if (v.shape == VisualSpec::Shape::Mesh) {
        EXPECT_TRUE(fs::exists(v.file)) << entry << ": " << v.file;
      }
  }
  ::unsetenv("ROS_PACKAGE_PATH");
  // A relative path is taken from the URDF's folder; file:// is a path.
  const std::string xml = robot(link("a") + "<link name=\"b\"><visual><geometry><mesh filename=\"../meshes/finger.stl\" "
                                            "scale=\"2 2 2\"/></geometry></visual><visual><geometry><mesh filename=\"file://" +
                                (test_arm_package() / "meshes" / "hand.dae").string() +
                                "\"/></geometry></visual></link>" + joint("j", "revolute", "a", "b"));
  const ModelDescription rel = parse_urdf(xml, (test_arm_package() / "urdf" / "inline.urdf").string());
  ASSERT_EQ(rel.visuals.size(), 2u);
  EXPECT_TRUE(fs::exists(rel.visuals[0].file)) << rel.visuals[0].file;
  EXPECT_EQ(rel.visuals[0].size, Vec3(2, 2, 2));
  EXPECT_TRUE(fs::exists(rel.visuals[1].file)) << rel.visuals[1].file;
}

TEST(UrdfErrors, DrakeRotorTags) {
  auto with = [](const std::string& transmission) {
    return robot(link("a") + link("b", 1.0, "0 0 0", "0 0 0", 0.1, 0.1, 0.1) + link("c") + joint("j", "revolute", "a", "b") +
                 joint("f", "fixed", "b", "c") + transmission);
  };
  auto tr = [](const std::string& joint, const std::string& tags) {
    return "<transmission name=\"t\"><joint name=\"" + joint + "\"/><actuator name=\"m\">" + tags + "</actuator></transmission>";
  };
  // gear ratio 1 when absent
  io::UrdfExtras ex;
  const ModelDescription d = parse_urdf(with(tr("j", "<drake:rotor_inertia value=\"0.5\"/>")), "inline.urdf", {}, ex);
  EXPECT_EQ(build_model(d).armature[0], 0.5);
  EXPECT_TRUE(parse_fails_with(with(tr("j", "<drake:rotor_inertia value=\"abc\"/>")),
                               {"transmission 't' <drake:rotor_inertia>", "expected a finite number, got 'abc'"}));
  EXPECT_TRUE(parse_fails_with(with(tr("j", "<drake:gear_ratio/>")), {"<drake:gear_ratio> has no value attribute"}));
  EXPECT_TRUE(parse_fails_with(with(tr("j", "<drake:rotor_inertia value=\"-1\"/>")), {"expected a value >= 0"}));
  EXPECT_TRUE(parse_fails_with(with(tr("f", "<drake:rotor_inertia value=\"1\"/>")), {"joint 'f' is fixed"}));
  EXPECT_TRUE(parse_fails_with(with(tr("nope", "<drake:rotor_inertia value=\"1\"/>")), {"unknown joint 'nope'"}));
  EXPECT_TRUE(parse_fails_with(with(tr("j", "<drake:rotor_inertia value=\"1\"/>") + tr("j", "<drake:gear_ratio value=\"2\"/>")),
                               {"two transmissions"}));
  // ROS transmissions without Drake's tags are ignored.
  EXPECT_EQ(build_model(parse_urdf(with(tr("j", "<mechanicalReduction>50</mechanicalReduction>")), "inline.urdf")).armature[0], 0.0);
}
