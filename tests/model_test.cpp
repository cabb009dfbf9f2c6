// Model building: DH conventions, folding of fixed joints, trees, base transform,
// pseudo-inertia and the validation of user input.
#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

using namespace refdyn;
using refdyn::test::near;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Standard DH link transform written out entry by entry (Spong's A_i):
/// A = Rz(θ) Tz(d) Tx(a) Rx(α).
Mat4 dh_standard(double theta, double d, double a, double alpha) {
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  Mat4 A;
  A << ct, -st * ca, st * sa, a * ct,  //
      st, ct * ca, -ct * sa, a * st,   //
      0, sa, ca, d,                    //
      0, 0, 0, 1;
  return A;
}

/// Modified (Craig) DH link transform written out entry by entry:
/// A = Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ_i) Tz(d_i).
Mat4 dh_modified(double theta, double d, double a, double alpha) {
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  Mat4 A;
  A << ct, -st, 0, a,                 //
      st * ca, ct * ca, -sa, -sa * d,  //
      st * sa, ct * sa, ca, ca * d,    //
      0, 0, 0, 1;
  return A;
}

std::vector<DHRow> two_link_rows() {
  std::vector<DHRow> rows(2);
  rows[0].type = JointType::Revolute;
  rows[0].d = 0.5;
  rows[0].a = 0.3;
  rows[0].alpha = 90 * kDeg;
  rows[0].inertia = {1.0, Vec3(0.1, 0, 0), Vec3(0.01, 0.02, 0.02).asDiagonal()};
  rows[1].type = JointType::Revolute;
  rows[1].d = 0.1;
  rows[1].a = 0.4;
  rows[1].alpha = 0.0;
  rows[1].inertia = {2.0, Vec3(0.2, 0, 0), Vec3(0.01, 0.03, 0.03).asDiagonal()};
  return rows;
}

/// Expects build_model(d) to throw refdyn::Error whose message contains every substring.
::testing::AssertionResult build_fails_with(const ModelDescription& d, const std::vector<std::string>& parts) {
  try {
    build_model(d);
  } catch (const Error& e) {
    const std::string msg = e.what();
    for (const auto& p : parts)
      if (msg.find(p) == std::string::npos)
        return ::testing::AssertionFailure() << "message \"" << msg << "\" lacks \"" << p << "\"";
    return ::testing::AssertionSuccess() << msg;
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "threw a non-refdyn exception: " << e.what();
  }
  return ::testing::AssertionFailure() << "build_model did not throw";
}

Mat3 sym_point_inertia(double m, const Vec3& d) {
  return m * (d.squaredNorm() * Mat3::Identity() - d * d.transpose());
}

/// Folds the fixed links of `d` by hand (independently of build_model): mass properties are
/// merged with the parallel-axis theorem into the movable link (or the world) they are rigidly
/// attached to, children placements and points are re-expressed in that link's frame.
ModelDescription fold_fixed_by_hand(const ModelDescription& d) {
  ModelDescription out;
  out.name = d.name;
  out.base = d.base;
  out.gravity = d.gravity;
  const size_t nl = d.links.size();
  std::vector<int> host(nl, -1);  // index in `out` of the movable link carrying link i (-1: world)
  std::vector<SE3> in_host(nl);   // pose of link i's frame in the host's link frame (base if -1)
  // Mass properties accumulated as point-mass moments: mass, first moment, and I about origin.
  struct Acc {
    double m = 0;
    Vec3 h = Vec3::Zero();
    Mat3 I = Mat3::Zero();  // about the host frame origin
  };
  std::vector<Acc> acc;
  auto add = [&](int hidx, const SE3& X, const LinkInertia& in) {
    if (hidx < 0) return;  // attached to the world: does not move, does not count
    const Vec3 c = X.act_point(in.com);
    Acc& a = acc[static_cast<size_t>(hidx)];
    a.m += in.mass;
    a.h += in.mass * c;
    a.I += X.R * in.I_com * X.R.transpose() + sym_point_inertia(in.mass, c);
  };
  for (size_t i = 0; i < nl; ++i) {
    const LinkSpec& l = d.links[i];
    const int ph = l.parent < 0 ? -1 : host[static_cast<size_t>(l.parent)];
    const SE3 parent_pose = l.parent < 0 ? SE3::Identity() : in_host[static_cast<size_t>(l.parent)];
    if (l.type == JointType::Fixed) {
      host[i] = ph;
      in_host[i] = parent_pose * l.placement * l.link_offset;
      add(ph, in_host[i], l.inertia);
      continue;
    }
    LinkSpec n = l;
    n.parent = ph;
    n.placement = parent_pose * l.placement;
    n.inertia = {};
    host[i] = out.add_link(n);
    in_host[i] = SE3::Identity();
    acc.push_back({});
    add(host[i], SE3::Identity(), l.inertia);
  }
  for (size_t k = 0; k < acc.size(); ++k) {
    const Acc& a = acc[k];
    LinkInertia& in = out.links[k].inertia;
    in.mass = a.m;
    in.com = a.m > 0 ? Vec3(a.h / a.m) : Vec3::Zero();
    in.I_com = a.I - sym_point_inertia(a.m, in.com);
    in.I_com = (0.5 * (in.I_com + in.I_com.transpose())).eval();
  }
  for (const PointSpec& p : d.points) {
    if (p.link == "world" || p.link == "base") {
      out.points.push_back(p);
      continue;
    }
    size_t li = 0;
    while (d.links[li].name != p.link) ++li;
    const Vec3 pos = in_host[li].act_point(p.position);
    if (host[li] < 0)
      out.add_point(p.name, "base", pos);
    else
      out.add_point(p.name, out.links[static_cast<size_t>(host[li])].name, pos);
  }
  return out;
}

LinkSpec simple_link(const std::string& name, int parent) {
  LinkSpec l;
  l.name = name;
  l.parent = parent;
  l.placement = SE3::trans(Vec3(0.3, 0, 0.1));
  l.inertia = {1.5, Vec3(0.1, 0.0, 0.0), Vec3(0.02, 0.03, 0.04).asDiagonal()};
  return l;
}

ModelDescription two_simple_links() {
  ModelDescription d;
  d.add_link(simple_link("upperarm", -1));
  d.add_link(simple_link("forearm", 0));
  d.add_point("wrist", "forearm", Vec3(0.2, 0, 0));
  return d;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Denavit–Hartenberg conventions

TEST(ModelDH, StandardTwoLinkHandWorked) {
  // Worked by hand at q = (90°, −90°):
  //   A1 = Rz(90°)Tz(0.5)Tx(0.3)Rx(90°) = [[0,0,1,0],[1,0,0,0.3],[0,1,0,0.5]]
  //   A2 = Rz(−90°)Tz(0.1)Tx(0.4)        = [[0,1,0,0],[−1,0,0,−0.4],[0,0,1,0.1]]
  //   A1 A2 = [[0,0,1,0.1],[0,1,0,0.3],[−1,0,0,0.1]]
  const ModelDescription d = from_dh(two_link_rows(), DHConvention::Standard);
  const Model model = build_model(d);
  ASSERT_EQ(model.nq, 2);
  Data data(model);
  Eigen::VectorXd q(2);
  q << 90 * kDeg, -90 * kDeg;
  forward_kinematics(model, data, q);
  Mat4 T1, T2;
  T1 << 0, 0, 1, 0, 1, 0, 0, 0.3, 0, 1, 0, 0.5, 0, 0, 0, 1;
  T2 << 0, 0, 1, 0.1, 0, 1, 0, 0.3, -1, 0, 0, 0.1, 0, 0, 0, 1;
  EXPECT_TRUE(near(link_transform(model, data, 0).matrix(), T1, 0, 1e-15));
  EXPECT_TRUE(near(link_transform(model, data, 1).matrix(), T2, 0, 1e-15));
}

TEST(ModelDH, ModifiedTwoLinkHandWorked) {
  // Craig's convention, same rows, q = (90°, −90°):
  //   A1 = Rx(90°)Tx(0.3)Rz(90°)Tz(0.5)  = [[0,−1,0,0.3],[0,0,−1,−0.5],[1,0,0,0]]
  //   A2 = Rx(0)Tx(0.4)Rz(−90°)Tz(0.1)   = [[0,1,0,0.4],[−1,0,0,0],[0,0,1,0.1]]
  //   A1 A2 = [[1,0,0,0.3],[0,0,−1,−0.6],[0,1,0,0.4]]
  const ModelDescription d = from_dh(two_link_rows(), DHConvention::Modified);
  const Model model = build_model(d);
  Data data(model);
  Eigen::VectorXd q(2);
  q << 90 * kDeg, -90 * kDeg;
  forward_kinematics(model, data, q);
  Mat4 T1, T2;
  T1 << 0, -1, 0, 0.3, 0, 0, -1, -0.5, 1, 0, 0, 0, 0, 0, 0, 1;
  T2 << 1, 0, 0, 0.3, 0, 0, -1, -0.6, 0, 1, 0, 0.4, 0, 0, 0, 1;
  EXPECT_TRUE(near(link_transform(model, data, 0).matrix(), T1, 0, 1e-15));
  EXPECT_TRUE(near(link_transform(model, data, 1).matrix(), T2, 0, 1e-15));
}

TEST(ModelDH, BothConventionsMatchTextbookMatricesAtRandomConfigurations) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ang(-3.0, 3.0), len(-0.7, 0.7);
  for (int rep = 0; rep < 20; ++rep) {
    std::vector<DHRow> rows(4);
    for (auto& r : rows) {
      r.type = ang(rng) > 0 ? JointType::Revolute : JointType::Prismatic;
      r.theta = ang(rng);
      r.d = len(rng);
      r.a = len(rng);
      r.alpha = ang(rng);
      r.inertia = {1.0, Vec3::Zero(), Vec3(0.01, 0.01, 0.01).asDiagonal()};
    }
    const Eigen::VectorXd q = test::random_vector(rng, 4, 2.0);
    for (DHConvention conv : {DHConvention::Standard, DHConvention::Modified}) {
      const Model model = build_model(from_dh(rows, conv));
      Data data(model);
      forward_kinematics(model, data, q);
      Mat4 T = Mat4::Identity();
      for (int i = 0; i < 4; ++i) {
        const DHRow& r = rows[static_cast<size_t>(i)];
        const bool rev = r.type == JointType::Revolute;
        const double theta = rev ? r.theta + q[i] : r.theta, dd = rev ? r.d : r.d + q[i];
        T = T * (conv == DHConvention::Standard ? dh_standard(theta, dd, r.a, r.alpha)
                                                : dh_modified(theta, dd, r.a, r.alpha));
        EXPECT_TRUE(near(link_transform(model, data, i).matrix(), T, 1e-14, 1e-14))
            << "rep " << rep << " link " << i << (conv == DHConvention::Standard ? " standard" : " modified");
      }
    }
  }
}

TEST(ModelDH, LinkNamesAndJointNames) {
  std::vector<DHRow> rows = two_link_rows();
  rows[1].name = "elbow";
  const Model model = build_model(from_dh(rows));
  EXPECT_EQ(model.body_name[0], "link1");
  EXPECT_EQ(model.joint_name[0], "q1");
  EXPECT_EQ(model.body_index("elbow"), 1);
  EXPECT_EQ(model.joint_index("elbow"), 1);
}

// ---------------------------------------------------------------------------------------------
// Fixed joints

TEST(ModelFixedJoints, HandWorkedMergeOfOneFixedLink) {
  // Chain: shoulder (revolute z) → upper (revolute x) → bracket (fixed, massive) → hand (prismatic).
  ModelDescription a;
  LinkSpec s;
  s.name = "shoulder";
  s.placement = SE3::trans(Vec3(0, 0, 0.4));
  s.inertia = {3.0, Vec3(0, 0, 0.1), Vec3(0.05, 0.05, 0.02).asDiagonal()};
  a.add_link(s);
  LinkSpec u;
  u.name = "upper";
  u.parent = 0;
  u.axis = Vec3::UnitX();
  u.placement = SE3{Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()).toRotationMatrix(), Vec3(0.1, 0.2, 0.3)};
  u.link_offset = SE3{Eigen::AngleAxisd(-0.7, Vec3(0, 1, 1).normalized()).toRotationMatrix(), Vec3(0, 0.05, 0)};
  u.inertia = {2.0, Vec3(0.2, 0, 0.05), Vec3(0.01, 0.04, 0.04).asDiagonal()};
  a.add_link(u);
  LinkSpec f;
  f.name = "bracket";
  f.parent = 1;
  f.type = JointType::Fixed;
  f.placement = SE3{Eigen::AngleAxisd(1.1, Vec3(0, 0, 1)).toRotationMatrix(), Vec3(0.4, 0, 0)};
  f.link_offset = SE3{Eigen::AngleAxisd(0.4, Vec3(1, 0, 0)).toRotationMatrix(), Vec3(0, 0, 0.02)};
  f.inertia = {1.2, Vec3(0.03, -0.02, 0.01), Vec3(0.004, 0.006, 0.008).asDiagonal()};
  a.add_link(f);
  LinkSpec h;
  h.name = "hand";
  h.parent = 2;
  h.type = JointType::Prismatic;
  h.axis = Vec3(0, 1, 1).normalized();
  h.placement = SE3::trans(Vec3(0.1, 0.1, 0));
  h.inertia = {0.5, Vec3(0, 0, 0.05), Vec3(0.001, 0.001, 0.0005).asDiagonal()};
  a.add_link(h);
  a.add_point("tool", "bracket", Vec3(0.05, 0.05, 0.05));
  a.gravity = Vec3(0.1, -0.3, -9.81);

  // The same chain with the bracket merged into "upper" by hand. In upper's link frame the
  // bracket frame is X = P_f·L_f; its com is X c_f, its inertia R I Rᵀ, then parallel axis.
  ModelDescription b;
  b.gravity = a.gravity;
  b.add_link(s);
  const SE3 X = f.placement * f.link_offset;
  const double m = u.inertia.mass + f.inertia.mass;
  const Vec3 cu = u.inertia.com, cf = X.act_point(f.inertia.com);
  const Vec3 c = (u.inertia.mass * cu + f.inertia.mass * cf) / m;
  const Vec3 du = cu - c, df = cf - c;
  Mat3 I = u.inertia.I_com + X.R * f.inertia.I_com * X.R.transpose();
  I += u.inertia.mass * (du.squaredNorm() * Mat3::Identity() - du * du.transpose());
  I += f.inertia.mass * (df.squaredNorm() * Mat3::Identity() - df * df.transpose());
  LinkSpec um = u;
  um.inertia = {m, c, I};
  b.add_link(um);
  LinkSpec hm = h;
  hm.parent = 1;
  hm.placement = X * h.placement;
  b.add_link(hm);
  b.add_point("tool", "upper", X.act_point(Vec3(0.05, 0.05, 0.05)));

  const Model ma = build_model(a), mb = build_model(b);
  ASSERT_EQ(ma.nq, 3);
  ASSERT_EQ(mb.nq, 3);
  EXPECT_EQ(ma.body_name[1], "upper");
  EXPECT_EQ(ma.body_name[2], "hand");
  EXPECT_EQ(ma.parent[2], 1);
  EXPECT_NEAR(ma.total_mass(), 3.0 + 2.0 + 1.2 + 0.5, 1e-15);
  Data da(ma), db(mb);
  std::mt19937 rng(3);
  for (int rep = 0; rep < 10; ++rep) {
    const Eigen::VectorXd q = test::random_vector(rng, 3, 3.0), qd = test::random_vector(rng, 3, 2.0);
    EXPECT_TRUE(near(mass_matrix(ma, da, q), mass_matrix(mb, db, q), 1e-13));
    EXPECT_TRUE(near(bias_forces(ma, da, q, qd), bias_forces(mb, db, q, qd), 1e-13));
    EXPECT_TRUE(near(gravity_forces(ma, da, q), gravity_forces(mb, db, q), 1e-13));
    forward_kinematics(ma, da, q);
    forward_kinematics(mb, db, q);
    EXPECT_TRUE(near(point_position(ma, da, 0), point_position(mb, db, 0), 1e-14));
    EXPECT_TRUE(near(point_position(ma, da, 0), test::reference_point_position(a, q, "tool"), 1e-14));
  }
}

TEST(ModelFixedJoints, RandomChainsWithFixedLinksEqualHandFoldedChains) {
  std::mt19937 rng(99);
  for (int rep = 0; rep < 12; ++rep) {
    test::RandomChainOptions o;
    o.dof = 3 + rep % 6;
    o.with_fixed_joints = true;
    o.tree = rep % 3 == 2;
    o.modified_dh = rep % 2 == 1;
    ModelDescription a = test::random_chain(rng, o);
    // Also a fixed link hanging from the base, carrying a point, and a point on a fixed link.
    LinkSpec w;
    w.name = "pedestal";
    w.type = JointType::Fixed;
    w.placement = SE3::trans(Vec3(0.1, 0.2, 0.3));
    w.inertia = {4.0, Vec3(0, 0, 0.1), Vec3(0.1, 0.1, 0.1).asDiagonal()};
    a.add_link(w);
    a.add_point("on_pedestal", "pedestal", Vec3(0.01, 0.02, 0.03));
    a.add_point("on_fixed", a.links[2].name, Vec3(0.1, -0.1, 0.2));
    ASSERT_EQ(a.links[2].type, JointType::Fixed);
    const ModelDescription b = fold_fixed_by_hand(a);
    const Model ma = build_model(a), mb = build_model(b);
    ASSERT_EQ(ma.nq, o.dof);
    ASSERT_EQ(mb.nq, o.dof);
    for (int i = 0; i < ma.nq; ++i) EXPECT_EQ(ma.parent[i], mb.parent[i]);
    Data da(ma), db(mb);
    const Eigen::VectorXd q = test::random_vector(rng, o.dof, 3.0), qd = test::random_vector(rng, o.dof, 2.0);
    EXPECT_TRUE(near(mass_matrix(ma, da, q), mass_matrix(mb, db, q), 1e-12)) << "rep " << rep;
    EXPECT_TRUE(near(bias_forces(ma, da, q, qd), bias_forces(mb, db, q, qd), 1e-12)) << "rep " << rep;
    EXPECT_TRUE(near(gravity_forces(ma, da, q), gravity_forces(mb, db, q), 1e-12)) << "rep " << rep;
    EXPECT_NEAR(kinetic_energy(ma, da, q, qd), kinetic_energy(mb, db, q, qd),
                1e-12 * std::abs(kinetic_energy(mb, db, q, qd)));
    forward_kinematics(ma, da, q);
    forward_kinematics(mb, db, q);
    for (const std::string p : {"tip", "on_pedestal", "on_fixed"}) {
      const Vec3 ref = test::reference_point_position(a, q, p);
      EXPECT_TRUE(near(point_position(ma, da, ma.point_index(p)), ref, 1e-13)) << p << " rep " << rep;
      EXPECT_TRUE(near(point_position(mb, db, mb.point_index(p)), ref, 1e-13)) << p << " rep " << rep;
    }
    EXPECT_EQ(ma.point_body[static_cast<size_t>(ma.point_index("on_pedestal"))], -1);
  }
}

// ---------------------------------------------------------------------------------------------
// Trees and the base transform

TEST(ModelTree, ParentsSupportsAndKinematicIndependenceAreRespected) {
  std::mt19937 rng(2024);
  for (int rep = 0; rep < 10; ++rep) {
    test::RandomChainOptions o;
    o.dof = 4 + rep;
    o.tree = true;
    o.modified_dh = rep % 2 == 0;
    const ModelDescription d = test::random_chain(rng, o);
    const Model model = build_model(d);
    ASSERT_EQ(model.nq, o.dof);
    bool branched = false;
    for (int i = 0; i < model.nq; ++i) {
      EXPECT_EQ(model.parent[i], d.links[static_cast<size_t>(i)].parent);
      EXPECT_LT(model.parent[i], i);
      if (i > 0 && model.parent[i] != i - 1) branched = true;
      // support: root first, ends in i, each entry the parent of the next
      const auto& s = model.support[static_cast<size_t>(i)];
      ASSERT_FALSE(s.empty());
      EXPECT_EQ(s.back(), i);
      EXPECT_EQ(model.parent[s.front()], -1);
      for (size_t k = 1; k < s.size(); ++k) EXPECT_EQ(model.parent[s[k]], s[k - 1]);
    }
    EXPECT_TRUE(branched || o.dof < 5) << "seeded tree happens to be a chain; pick another seed";
    Data data(model), data2(model);
    const Eigen::VectorXd q = test::random_vector(rng, o.dof, 3.0);
    forward_kinematics(model, data, q);
    const std::vector<SE3> ref = test::reference_link_poses(d, q);
    for (int i = 0; i < model.nq; ++i)
      EXPECT_TRUE(near(link_transform(model, data, i).matrix(), ref[static_cast<size_t>(i)].matrix(), 1e-13))
          << "body " << i;
    // Moving joint j moves exactly the bodies that have j in their support.
    const Eigen::MatrixXd M = mass_matrix(model, data2, q);
    for (int j = 0; j < model.nq; ++j) {
      Eigen::VectorXd q2 = q;
      q2[j] += 0.3;
      forward_kinematics(model, data2, q2);
      for (int i = 0; i < model.nq; ++i) {
        const auto& s = model.support[static_cast<size_t>(i)];
        const bool moves = std::find(s.begin(), s.end(), j) != s.end();
        const double change = (data2.oMi[i].matrix() - data.oMi[i].matrix()).norm();
        if (moves) {
          EXPECT_GT(change, 1e-6) << "joint " << j << " should move body " << i;
        } else {
          EXPECT_EQ(change, 0.0) << "joint " << j << " should not move body " << i;
        }
      }
      // M_ij = 0 exactly when neither of i, j is an ancestor of the other.
      for (int i = 0; i < model.nq; ++i) {
        const auto& si = model.support[static_cast<size_t>(i)];
        const auto& sj = model.support[static_cast<size_t>(j)];
        const bool related = std::find(si.begin(), si.end(), j) != si.end() ||
                             std::find(sj.begin(), sj.end(), i) != sj.end();
        if (!related) {
          EXPECT_EQ(M(i, j), 0.0) << i << "," << j;
        }
      }
    }
  }
}

TEST(ModelBase, BaseTransformMovesEverythingRigidly) {
  std::mt19937 rng(11);
  for (int rep = 0; rep < 6; ++rep) {
    test::RandomChainOptions o;
    o.dof = 5;
    o.random_base = false;
    o.tree = rep % 2 == 1;
    o.with_fixed_joints = rep % 3 == 0;
    ModelDescription d0 = test::random_chain(rng, o);
    ModelDescription d1 = d0;
    const SE3 B{Eigen::AngleAxisd(0.8, Vec3(1, -2, 0.5).normalized()).toRotationMatrix(), Vec3(0.3, -1.0, 2.0)};
    d1.base = B;
    d1.gravity = B.R * d0.gravity;  // same gravity relative to the robot
    ModelDescription d2 = d0;       // same base, gravity left in the world
    d2.base = B;
    const Model m0 = build_model(d0), m1 = build_model(d1), m2 = build_model(d2);
    Data a(m0), b(m1), c(m2);
    const Eigen::VectorXd q = test::random_vector(rng, o.dof, 3.0), qd = test::random_vector(rng, o.dof);
    forward_kinematics(m0, a, q);
    forward_kinematics(m1, b, q);
    for (int i = 0; i < m0.nq; ++i)
      EXPECT_TRUE(near(link_transform(m1, b, i).matrix(), (B * link_transform(m0, a, i)).matrix(), 1e-13));
    EXPECT_TRUE(near(point_position(m1, b, 0), B.act_point(point_position(m0, a, 0)), 1e-13));
    EXPECT_TRUE(near(point_position(m1, b, 0), test::reference_point_position(d1, q, "tip"), 1e-13));
    EXPECT_TRUE(near(mass_matrix(m1, b, q), mass_matrix(m0, a, q), 1e-12));
    EXPECT_TRUE(near(bias_forces(m1, b, q, qd), bias_forces(m0, a, q, qd), 1e-12));
    EXPECT_TRUE(near(mass_matrix(m2, c, q), mass_matrix(m0, a, q), 1e-12));
    // With gravity fixed in the world the gravity vector must change (B rotates the robot).
    EXPECT_GT(test::rel_diff(gravity_forces(m2, c, q), gravity_forces(m0, a, q)), 1e-3);
  }
}

// ---------------------------------------------------------------------------------------------
// Pseudo-inertia

TEST(ModelPseudoInertia, EightPointMassesAtCubeCorners) {
  // Unequal point masses at the corners of a rotated, shifted cube: H = Σ m_k r̄_k r̄_kᵀ.
  const Mat3 Rc = Eigen::AngleAxisd(0.6, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  const Vec3 centre(0.2, -0.1, 0.35);
  const double half = 0.15;
  std::vector<double> mk = {0.5, 1.0, 1.5, 2.0, 0.7, 0.9, 1.1, 1.3};
  std::vector<Vec3> rk;
  for (int sx : {-1, 1})
    for (int sy : {-1, 1})
      for (int sz : {-1, 1}) rk.push_back(centre + Rc * Vec3(sx * half, sy * half, sz * half));
  Mat4 H_direct = Mat4::Zero();
  double m = 0;
  Vec3 h = Vec3::Zero();
  for (size_t k = 0; k < 8; ++k) {
    Eigen::Vector4d rb;
    rb << rk[k], 1.0;
    H_direct += mk[k] * rb * rb.transpose();
    m += mk[k];
    h += mk[k] * rk[k];
  }
  const Vec3 c = h / m;
  Mat3 I_com = Mat3::Zero();
  for (size_t k = 0; k < 8; ++k) I_com += sym_point_inertia(mk[k], rk[k] - c);

  LinkSpec l;
  l.name = "cube";
  l.inertia = {m, c, I_com};
  ModelDescription d;
  d.add_link(l);
  const Model model = build_model(d);
  EXPECT_TRUE(near(model.pseudo_inertia(0), H_direct, 1e-14));

  // The documented closed form [[½tr(I_O)1 − I_O, m c],[m cᵀ, m]] with I_O about the origin.
  const Mat3 I_O = I_com + sym_point_inertia(m, c);
  Mat4 H_formula = Mat4::Zero();
  H_formula.topLeftCorner<3, 3>() = 0.5 * I_O.trace() * Mat3::Identity() - I_O;
  H_formula.topRightCorner<3, 1>() = m * c;
  H_formula.bottomLeftCorner<1, 3>() = m * c.transpose();
  H_formula(3, 3) = m;
  EXPECT_TRUE(near(H_formula, H_direct, 1e-14));

  // With a link offset L the body frame differs from the link frame: H_body = L H_link Lᵀ
  // (r̄_body = L r̄_link for each mass), also a direct sum over the points.
  LinkSpec l2 = l;
  l2.link_offset = SE3{Eigen::AngleAxisd(-1.2, Vec3(0.3, -0.4, 1).normalized()).toRotationMatrix(), Vec3(0.5, 0.1, -0.2)};
  ModelDescription d2;
  d2.add_link(l2);
  const Model model2 = build_model(d2);
  Mat4 H_body = Mat4::Zero();
  for (size_t k = 0; k < 8; ++k) {
    Eigen::Vector4d rb;
    rb << l2.link_offset.act_point(rk[k]), 1.0;
    H_body += mk[k] * rb * rb.transpose();
  }
  EXPECT_TRUE(near(model2.pseudo_inertia(0), H_body, 1e-14));
  const Mat4 L = l2.link_offset.matrix();
  EXPECT_TRUE(near(model2.pseudo_inertia(0), L * H_direct * L.transpose(), 1e-14));
  // Data copies it.
  Data data(model2);
  EXPECT_TRUE(near(data.H[0], H_body, 1e-14));
}

// ---------------------------------------------------------------------------------------------
// Validation

TEST(ModelValidation, NegativeMass) {
  ModelDescription d = two_simple_links();
  d.links[1].inertia.mass = -2.5;
  EXPECT_TRUE(build_fails_with(d, {"forearm", "mass", "-2.5", "expected", "got"}));
}

TEST(ModelValidation, NonPositiveSemiDefiniteInertia) {
  ModelDescription d = two_simple_links();
  d.links[1].inertia.I_com = Vec3(0.02, 0.03, -0.125).asDiagonal();
  EXPECT_TRUE(build_fails_with(d, {"forearm", "positive semi-definite", "-0.125"}));
}

TEST(ModelValidation, NonSymmetricInertia) {
  ModelDescription d = two_simple_links();
  d.links[0].inertia.I_com(0, 1) = 0.01;
  EXPECT_TRUE(build_fails_with(d, {"upperarm", "symmetric"}));
}

TEST(ModelValidation, TriangleInequalityViolation) {
  ModelDescription d = two_simple_links();
  d.links[1].inertia.I_com = Vec3(0.01, 0.02, 0.75).asDiagonal();
  EXPECT_TRUE(build_fails_with(d, {"forearm", "triangle", "0.75", "0.01", "0.02"}));
  // The limiting case (a thin rod: 0, a, a) is physical and accepted.
  d.links[1].inertia.I_com = Vec3(0.0, 0.02, 0.02).asDiagonal();
  EXPECT_NO_THROW(build_model(d));
}

TEST(ModelValidation, UnknownParent) {
  ModelDescription d = two_simple_links();
  d.links[1].parent = 7;
  EXPECT_TRUE(build_fails_with(d, {"forearm", "parent", "7", "expected", "got"}));
  d.links[1].parent = -3;
  EXPECT_TRUE(build_fails_with(d, {"forearm", "parent", "-3"}));
}

TEST(ModelValidation, ParentListedAfterChild) {
  ModelDescription d = two_simple_links();
  d.links[0].parent = 1;
  EXPECT_TRUE(build_fails_with(d, {"upperarm", "parent", "1", "before"}));
  d = two_simple_links();
  d.links[1].parent = 1;  // its own parent
  EXPECT_TRUE(build_fails_with(d, {"forearm", "parent", "1"}));
}

TEST(ModelValidation, NaNInMassComInertiaPlacement) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  {
    ModelDescription d = two_simple_links();
    d.links[1].inertia.mass = nan;
    EXPECT_TRUE(build_fails_with(d, {"forearm", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[1].inertia.com.y() = nan;
    EXPECT_TRUE(build_fails_with(d, {"forearm", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[0].inertia.I_com(2, 2) = nan;
    EXPECT_TRUE(build_fails_with(d, {"upperarm", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[1].placement.p.x() = nan;
    EXPECT_TRUE(build_fails_with(d, {"forearm", "placement", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[1].placement.R(0, 0) = std::numeric_limits<double>::infinity();
    EXPECT_TRUE(build_fails_with(d, {"forearm", "placement", "infinity"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[0].link_offset.p.z() = nan;
    EXPECT_TRUE(build_fails_with(d, {"upperarm", "link offset", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.links[1].offset = nan;
    EXPECT_TRUE(build_fails_with(d, {"forearm", "offset"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.base.p.x() = nan;
    EXPECT_TRUE(build_fails_with(d, {"base", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.gravity.z() = nan;
    EXPECT_TRUE(build_fails_with(d, {"gravity", "NaN"}));
  }
  {
    ModelDescription d = two_simple_links();
    d.points[0].position.x() = nan;
    EXPECT_TRUE(build_fails_with(d, {"wrist", "finite"}));
  }
}

TEST(ModelValidation, NotARotation) {
  ModelDescription d = two_simple_links();
  d.links[1].placement.R = Vec3(1, 1, 2).asDiagonal();
  EXPECT_TRUE(build_fails_with(d, {"forearm", "placement", "rotation"}));
  d = two_simple_links();
  d.links[1].placement.R = Vec3(1, 1, -1).asDiagonal();  // a reflection
  EXPECT_TRUE(build_fails_with(d, {"forearm", "placement", "det"}));
}

TEST(ModelValidation, DuplicateNames) {
  ModelDescription d = two_simple_links();
  d.links[1].name = "upperarm";
  d.points.clear();
  EXPECT_TRUE(build_fails_with(d, {"upperarm", "duplicate"}));
  d = two_simple_links();
  d.add_point("wrist", "upperarm", Vec3::Zero());
  EXPECT_TRUE(build_fails_with(d, {"wrist", "duplicate"}));
}

TEST(ModelValidation, PointOnUnknownLinkSuggestsTheClosestName) {
  ModelDescription d = two_simple_links();
  d.add_point("elbow", "forarm", Vec3::Zero());
  EXPECT_TRUE(build_fails_with(d, {"elbow", "forarm", "did you mean", "'forearm'"}));
  // Far from every name: the valid names are listed instead.
  d = two_simple_links();
  d.add_point("elbow", "gripper_mount", Vec3::Zero());
  EXPECT_TRUE(build_fails_with(d, {"gripper_mount", "upperarm", "forearm"}));
}

TEST(ModelValidation, MasslessLinkWithInertia) {
  ModelDescription d = two_simple_links();
  d.links[1].inertia.mass = 0.0;
  EXPECT_TRUE(build_fails_with(d, {"forearm", "massless"}));
  // A massless link without inertia is fine (e.g. an intermediate frame).
  d.links[1].inertia.I_com.setZero();
  EXPECT_NO_THROW(build_model(d));
}

TEST(ModelValidation, ZeroAxisAndBadLimits) {
  ModelDescription d = two_simple_links();
  d.links[1].axis = Vec3::Zero();
  EXPECT_TRUE(build_fails_with(d, {"forearm", "axis"}));
  d = two_simple_links();
  d.links[0].limits.lower = 1.0;
  d.links[0].limits.upper = -1.0;
  EXPECT_TRUE(build_fails_with(d, {"upperarm", "lower <= upper", "1 > -1"}));
}

// A Data belongs to the model it was built for (and to copies of it): the checked algorithms
// refuse another model's workspace with a clear error instead of reading out of its bounds.
TEST(Data, WorkspaceOfAnotherModelIsRefused) {
  std::mt19937 rng(57);
  ModelDescription d3 = test::random_chain(rng, {.dof = 3}), d5 = test::random_chain(rng, {.dof = 5});
  d3.add_point("p", d3.links.back().name, Vec3(0.1, 0, 0));
  const Model m3 = build_model(d3), m5 = build_model(d5), m3_again = build_model(d3);
  const Model m3_copy = m3;
  Data data5(m5), data3(m3);
  const Eigen::VectorXd q3 = Eigen::VectorXd::Zero(3);
  const std::vector<std::string> needles = {"another model", "Data data(model)"};
  test::expect_error_mentioning([&] { mass_matrix(m3, data5, q3); }, needles);
  test::expect_error_mentioning([&] { inverse_dynamics(m3, data5, q3, q3, q3); }, needles);
  test::expect_error_mentioning([&] { forward_kinematics(m3, data5, q3); }, needles);
  test::expect_error_mentioning([&] { point_position(m3, data5, 0); }, needles);
  test::expect_error_mentioning([&] { kinetic_energy(m3, data5, q3, q3); }, needles);
  // Same size, but built by another build_model call: also refused.
  test::expect_error_mentioning([&] { mass_matrix(m3_again, data3, q3); }, needles);
  // A copy of the model is the same model.
  EXPECT_NO_THROW(mass_matrix(m3_copy, data3, q3));
  EXPECT_TRUE(near(mass_matrix(m3_copy, data3, q3), mass_matrix(m3, data3, q3), 0, 0));
  EXPECT_NE(m3.id, m3_again.id);
  EXPECT_EQ(m3.id, m3_copy.id);
}
