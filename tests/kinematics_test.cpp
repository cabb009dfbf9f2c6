// Kinematics: the trace route's exact derivatives T_i^(l), T_ij^(l), point Jacobians and
// drift terms, against central finite differences and against each other.
//
// Finite-difference tolerances follow the error budget of a central difference with step h on
// quantities of size ~|p| (a few metres for these chains): truncation ~h²|f'''|/6, rounding
// ~ε|f|/h. With h = 1e-5 both are ~1e-10; the tolerances below leave a factor ~100 on top.
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"
#include "test_support.hpp"

#include <algorithm>

using namespace refdyn;
using refdyn::test::near;

namespace {

using Case = test::RandomModelCase;

/// The zoo (test::model_zoo) with 40 % prismatic joints, "mid" at (0.1, −0.2, 0.3) and "anchor"
/// at (1, 2, 3).
std::vector<Case> model_zoo(std::mt19937& rng, int dof) {
  test::ZooOptions o;
  o.prismatic_fraction = 0.4;
  o.mid = Vec3(0.1, -0.2, 0.3);
  o.anchor = Vec3(1, 2, 3);
  return test::model_zoo(rng, dof, o);
}

Eigen::VectorXd unit(int n, int i) { return Eigen::VectorXd::Unit(n, i); }

constexpr double kH = 1e-5;        // central-difference step
constexpr double kFdTol = 1e-8;    // relative tolerance for first derivatives by central FD

Vec3 vee(const Mat3& S) { return Vec3(S(2, 1) - S(1, 2), S(0, 2) - S(2, 0), S(1, 0) - S(0, 1)) / 2; }

}  // namespace

TEST(TraceKinematics, PosesEqualForwardKinematicsAndReference) {
  std::mt19937 rng(1);
  for (const Case& c : model_zoo(rng, 7)) {
    const Model model = build_model(c.desc);
    Data data(model);
    const Eigen::VectorXd q = test::random_vector(rng, model.nq, 3.0);
    trace_kinematics(model, data, q);
    const std::vector<SE3> ref = test::reference_link_poses(c.desc, q);
    const std::vector<int> link_of = test::movable_links(c.desc);
    for (int l = 0; l < model.nq; ++l) {
      EXPECT_TRUE(near(data.T[l], data.oMi[l].matrix(), 0, 0)) << c.label;
      const SE3 X = link_transform(model, data, l);
      EXPECT_TRUE(near(X.matrix(), (data.oMi[l] * model.link_offset[l]).matrix(), 0, 0));
      EXPECT_TRUE(near(X.matrix(), ref[static_cast<size_t>(link_of[l])].matrix(), 1e-13)) << c.label << " body " << l;
      // The body frame is the joint frame after the motion: its pose times the user link
      // offset is the user link frame, and the joint axis in {0} is R u.
      EXPECT_NEAR(X.R.determinant(), 1.0, 1e-13);
    }
  }
}

TEST(TraceKinematics, FirstDerivativesMatchCentralDifferencesOfThePose) {
  std::mt19937 rng(2);
  for (const Case& c : model_zoo(rng, 7)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    Data data(model), dp(model), dm(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0);
    trace_kinematics(model, data, q);
    for (int i = 0; i < n; ++i) {
      trace_kinematics(model, dp, q + kH * unit(n, i));
      trace_kinematics(model, dm, q - kH * unit(n, i));
      for (int l = 0; l < n; ++l) {
        const Mat4 fd = (dp.T[l] - dm.T[l]) / (2 * kH);
        const Mat4 an = trace_dT(model, data, l, i);
        EXPECT_TRUE(near(an, fd, kFdTol, kFdTol)) << c.label << " l=" << l << " i=" << i;
        const auto& s = model.support[static_cast<size_t>(l)];
        if (std::find(s.begin(), s.end(), i) == s.end()) {
          EXPECT_EQ(an.norm(), 0.0) << "joint " << i << " does not move body " << l;
        } else {
          EXPECT_GT(an.norm(), 0.1) << "joint " << i << " moves body " << l;
          // D_i T^(l) has a zero bottom row (a tangent vector of SE(3) at T^(l)).
          EXPECT_EQ(an.row(3).norm(), 0.0);
        }
      }
    }
  }
}

TEST(TraceKinematics, SecondDerivativesMatchCentralDifferences) {
  std::mt19937 rng(3);
  for (const Case& c : model_zoo(rng, 6)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    Data data(model), dp(model), dm(model), dpp(model), dpm(model), dmp(model), dmm(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0);
    trace_kinematics(model, data, q);
    const double h2 = 1e-4;  // second differences: rounding ~ε|T|/h² ≈ 1e-7, truncation ~h² ≈ 1e-8
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        // (a) central difference of the exact first derivative T_i^(l) along q_j
        trace_kinematics(model, dp, q + kH * unit(n, j));
        trace_kinematics(model, dm, q - kH * unit(n, j));
        // (b) mixed second difference of the pose itself
        trace_kinematics(model, dpp, q + h2 * (unit(n, i) + unit(n, j)));
        trace_kinematics(model, dpm, q + h2 * (unit(n, i) - unit(n, j)));
        trace_kinematics(model, dmp, q + h2 * (-unit(n, i) + unit(n, j)));
        trace_kinematics(model, dmm, q - h2 * (unit(n, i) + unit(n, j)));
        for (int l = 0; l < n; ++l) {
          const Mat4 an = trace_ddT(model, data, l, i, j);
          const Mat4 fd1 = (trace_dT(model, dp, l, i) - trace_dT(model, dm, l, i)) / (2 * kH);
          EXPECT_TRUE(near(an, fd1, kFdTol, kFdTol)) << c.label << " l=" << l << " i=" << i << " j=" << j;
          const Mat4 fd2 = (dpp.T[l] - dpm.T[l] - dmp.T[l] + dmm.T[l]) / (4 * h2 * h2);
          EXPECT_TRUE(near(an, fd2, 1e-5, 1e-5)) << c.label << " l=" << l << " i=" << i << " j=" << j;
          // Schwarz: the mixed partials are equal.
          EXPECT_TRUE(near(an, trace_ddT(model, data, l, j, i), 1e-15, 1e-15));
        }
      }
    }
  }
}

TEST(PointKinematics, JacobianMatchesFiniteDifferencesAndTraceRoute) {
  std::mt19937 rng(4);
  for (const Case& c : model_zoo(rng, 7)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    Data data(model), dp(model), dm(model), dt(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    for (const std::string name : {"tip", "mid"}) {
      const int p = model.point_index(name);
      forward_kinematics(model, data, q);
      point_jacobian(model, data, p);
      Eigen::Matrix<double, 3, Eigen::Dynamic> Cfd(3, n), Wfd(3, n);
      const int b = model.point_body[static_cast<size_t>(p)];
      for (int i = 0; i < n; ++i) {
        forward_kinematics(model, dp, q + kH * unit(n, i));
        forward_kinematics(model, dm, q - kH * unit(n, i));
        Cfd.col(i) = (point_position(model, dp, p) - point_position(model, dm, p)) / (2 * kH);
        const Mat3 Rdot = (dp.oMi[b].R - dm.oMi[b].R) / (2 * kH);
        Wfd.col(i) = vee(Rdot * data.oMi[b].R.transpose());
      }
      EXPECT_TRUE(near(data.Jp, Cfd, kFdTol, kFdTol)) << c.label << " " << name;
      EXPECT_TRUE(near(data.Jw, Wfd, kFdTol, kFdTol)) << c.label << " " << name;
      const TracePointKinematics tk = trace_point_kinematics(model, dt, p, q, qd);
      EXPECT_TRUE(near(tk.C, data.Jp, 1e-12)) << c.label << " " << name;
      EXPECT_TRUE(near(tk.position, point_position(model, data, p), 1e-14)) << c.label << " " << name;
      EXPECT_TRUE(near(tk.position, test::reference_point_position(c.desc, q, name), 1e-13)) << c.label;
    }
  }
}

TEST(PointKinematics, DriftMatchesJacobianDerivativeAndTraceRoute) {
  std::mt19937 rng(5);
  double worst_trace = 0;
  for (int dof : {1, 2, 7, 15}) {
    for (const Case& c : model_zoo(rng, dof)) {
      if (dof < 3 && c.desc.links.size() < 2) continue;
      const Model model = build_model(c.desc);
      const int n = model.nq;
      Data data(model), dp(model), dm(model), dt(model);
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
      for (const std::string name : {"tip", "mid"}) {
        const int p = model.point_index(name);
        forward_kinematics(model, data, q);
        point_jacobian(model, data, p);
        const Eigen::Matrix<double, 3, Eigen::Dynamic> C = data.Jp, W = data.Jw;
        const PointDrift pd = point_drift(model, data, p, qd);
        // d = (dC/dt) q̇ with dC/dt = Σ_i ∂C/∂q_i q̇_i: a central difference along q̇.
        forward_kinematics(model, dp, q + kH * qd);
        point_jacobian(model, dp, p);
        forward_kinematics(model, dm, q - kH * qd);
        point_jacobian(model, dm, p);
        const Vec3 d_fd = (dp.Jp - dm.Jp) / (2 * kH) * qd;
        const Vec3 wd_fd = (dp.Jw - dm.Jw) / (2 * kH) * qd;
        const double scale = C.cwiseAbs().maxCoeff() * qd.squaredNorm();  // size of the terms in d
        EXPECT_TRUE(near(pd.drift, d_fd, kFdTol, kFdTol * scale)) << c.label << " " << name << " n=" << n;
        EXPECT_TRUE(near(pd.omega_drift, wd_fd, kFdTol, kFdTol * scale)) << c.label << " " << name;
        EXPECT_TRUE(near(pd.velocity, C * qd, 1e-13)) << c.label << " " << name;
        EXPECT_TRUE(near(pd.omega, W * qd, 1e-13)) << c.label << " " << name;
        // The paper's route: d = (Σ_ij T_ij q̇_i q̇_j) r.
        const TracePointKinematics tk = trace_point_kinematics(model, dt, p, q, qd);
        EXPECT_TRUE(near(tk.d, pd.drift, 1e-10, 1e-10 * scale)) << c.label << " " << name << " n=" << n;
        worst_trace = std::max(worst_trace, test::rel_diff(tk.d, pd.drift, scale));
      }
    }
  }
  RecordProperty("worst_rel_trace_vs_recursive_drift", std::to_string(worst_trace));
}

TEST(PointKinematics, AccelerationIsJacobianTimesQddPlusDrift) {
  // Along q(t) = q + q̇ t + ½ q̈ t², r̈_P(0) = C q̈ + d; second central difference of r_P(t).
  std::mt19937 rng(6);
  for (const Case& c : model_zoo(rng, 6)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    Data data(model), dp(model), dm(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          qdd = test::random_vector(rng, n, 2.0);
    const int p = model.point_index("tip");
    forward_kinematics(model, data, q);
    point_jacobian(model, data, p);
    const Vec3 acc = data.Jp * qdd + point_drift(model, data, p, qd).drift;
    const double t = 1e-4;
    forward_kinematics(model, dp, q + t * qd + 0.5 * t * t * qdd);
    forward_kinematics(model, dm, q - t * qd + 0.5 * t * t * qdd);
    const Vec3 acc_fd =
        (point_position(model, dp, p) - 2 * point_position(model, data, p) + point_position(model, dm, p)) / (t * t);
    EXPECT_TRUE(near(acc, acc_fd, 1e-5, 1e-5)) << c.label;
  }
}

TEST(PointKinematics, WorldPointsAndOtherBranchesHaveZeroColumns) {
  std::mt19937 rng(8);
  for (const Case& c : model_zoo(rng, 6)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    Data data(model), dt(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
    forward_kinematics(model, data, q);
    const int a = model.point_index("anchor");
    EXPECT_EQ(model.point_body[static_cast<size_t>(a)], -1);
    EXPECT_TRUE(near(point_position(model, data, a), Vec3(1, 2, 3), 0, 0));
    point_jacobian(model, data, a);
    EXPECT_EQ(data.Jp.norm() + data.Jw.norm(), 0.0);
    const PointDrift pd = point_drift(model, data, a, qd);
    EXPECT_EQ(pd.drift.norm() + pd.velocity.norm(), 0.0);
    const TracePointKinematics tk = trace_point_kinematics(model, dt, a, q, qd);
    EXPECT_EQ(tk.C.norm() + tk.d.norm(), 0.0);
    EXPECT_TRUE(near(tk.position, Vec3(1, 2, 3), 0, 0));
    // Columns of joints outside the point's support are zero.
    const int p = model.point_index("mid");
    const int b = model.point_body[static_cast<size_t>(p)];
    point_jacobian(model, data, p);
    const auto& s = model.support[static_cast<size_t>(b)];
    for (int i = 0; i < n; ++i)
      if (std::find(s.begin(), s.end(), i) == s.end()) {
        EXPECT_EQ(data.Jp.col(i).norm() + data.Jw.col(i).norm(), 0.0) << c.label;
      }
  }
}

TEST(PointKinematics, JointPlacementComposesToForwardKinematics) {
  std::mt19937 rng(9);
  for (const Case& c : model_zoo(rng, 6)) {
    const Model model = build_model(c.desc);
    Data data(model);
    const Eigen::VectorXd q = test::random_vector(rng, model.nq, 3.0);
    forward_kinematics(model, data, q);
    for (int i = 0; i < model.nq; ++i) {
      const SE3 X = joint_placement(model, i, q[i]);
      EXPECT_TRUE(near(X.matrix(), data.liMi[i].matrix(), 0, 0));
      const int p = model.parent[i];
      const SE3 o = p < 0 ? X : data.oMi[p] * X;
      EXPECT_TRUE(near(o.matrix(), data.oMi[i].matrix(), 1e-15, 1e-15));
    }
  }
}
