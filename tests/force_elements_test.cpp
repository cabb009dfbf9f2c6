// Force elements: LuGre friction (paper (4.7)–(4.8)) against the formulas evaluated by hand, its
// exact ∂Q/∂q̇ against finite differences and its steady state; the flexible drive's sign (the
// joint follows the drive displacement); damping, spring and effort elements; ForceSet
// bookkeeping; parameter validation.
#include "refdyn/common/error.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <cmath>
#include <limits>
#include <numbers>

using namespace refdyn;
using refdyn::test::expect_error_mentioning;
using refdyn::test::near;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Three joints: j1 revolute, j2 revolute, j3 prismatic (all about / along their z axes).
Model three_joint_model() {
  std::vector<DHRow> rows(3);
  rows[0] = {JointType::Revolute, 0.1, 0.3, 0.2, 0.5, {1.0, Vec3(0.1, 0, 0), Mat3::Identity() * 0.02}, {}, "j1"};
  rows[1] = {JointType::Revolute, -0.2, 0.0, 0.4, -0.7, {2.0, Vec3(0, 0.1, 0), Mat3::Identity() * 0.03}, {}, "j2"};
  rows[2] = {JointType::Prismatic, 0.3, 0.2, 0.0, 0.0, {0.5, Vec3(0, 0, 0.1), Mat3::Identity() * 0.01}, {}, "j3"};
  return build_model(from_dh(rows));
}

/// LuGre by hand, straight from the formulas of the header / paper (4.7)–(4.8).
struct LuGreHand {
  double zdot, tau;
};
LuGreHand lugre_by_hand(const LuGreParams& p, double v, double z) {
  const double g = p.mu_k + (p.mu_s - p.mu_k) * std::exp(-(v / p.v_stribeck) * (v / p.v_stribeck));
  const double zd = v - p.sigma0 * std::abs(v) * z / g;
  return {zd, -(p.sigma0 * z + p.sigma1 * zd + p.sigma2 * v)};
}

}  // namespace

TEST(LuGre, StateDerivativeAndTorqueMatchTheFormulas) {
  const Model model = three_joint_model();
  LuGreParams p;  // the paper's rotary-joint values
  LuGreParams p2{0.3, 0.15, 40.0, 0.7, 0.25, 0.05};
  struct Pt {
    double v, z;
  };
  for (const LuGreParams& par : {p, p2}) {
    LuGreFriction f(model, "j2", par);
    EXPECT_EQ(f.num_states(), 1);
    EXPECT_EQ(f.joint(), 1);
    EXPECT_EQ(f.state_names(), std::vector<std::string>{"z_j2"});
    for (Pt pt : {Pt{0.0, 0.0}, Pt{0.0, 0.013}, Pt{0.1, 0.0}, Pt{0.1, 0.02}, Pt{-0.3, 0.04}, Pt{2.0, -0.01},
                  Pt{-1e-4, 1e-3}}) {
      Eigen::VectorXd q = Eigen::VectorXd::Zero(3), qd = Eigen::VectorXd::Zero(3);
      qd << 0.7, pt.v, -0.4;  // other joints' velocities must not matter
      Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
      Q[1] = 0.5;  // apply() adds
      double zdot = kNaN;
      f.apply(0.0, q, qd, &pt.z, Q, &zdot, nullptr);
      const LuGreHand h = lugre_by_hand(par, pt.v, pt.z);
      EXPECT_NEAR(zdot, h.zdot, 1e-15 * (1 + std::abs(h.zdot))) << "v = " << pt.v << ", z = " << pt.z;
      EXPECT_NEAR(Q[1] - 0.5, h.tau, 1e-14 * (1 + std::abs(h.tau))) << "v = " << pt.v << ", z = " << pt.z;
      EXPECT_EQ(Q[0], 0.0);
      EXPECT_EQ(Q[2], 0.0);
    }
  }
  // One point checked with numbers written out: μs = 0.1, μk = 0.2, σ0 = 5, σ1 = 0.025, σ2 = 0,
  // q̇S = 0.175; v = 0.175 (so exp(−1)), z = 0.01:
  //   g = 0.2 − 0.1/e = 0.16321205588285577, ż = 0.175 − 5·0.175·0.01/g = 0.12138876428...,
  //   τ = −(0.05 + 0.025 ż).
  {
    LuGreFriction f(model, "j1", p);
    Eigen::VectorXd q = Eigen::VectorXd::Zero(3), qd = Eigen::VectorXd::Zero(3), Q = Eigen::VectorXd::Zero(3);
    qd[0] = 0.175;
    double z = 0.01, zdot = 0;
    f.apply(0.0, q, qd, &z, Q, &zdot, nullptr);
    const double g = 0.2 - 0.1 * std::exp(-1.0);
    EXPECT_NEAR(g, 0.16321205588285578, 1e-16);
    EXPECT_NEAR(zdot, 0.175 - 0.00875 / g, 1e-15);
    EXPECT_NEAR(zdot, 0.12138876428172532, 1e-15);
    EXPECT_NEAR(Q[0], -(0.05 + 0.025 * zdot), 1e-15);
  }
}

TEST(LuGre, ExactVelocityJacobianMatchesFiniteDifferences) {
  const Model model = three_joint_model();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> uv(-1.0, 1.0), uz(-0.05, 0.05);
  const LuGreParams p2{0.3, 0.15, 40.0, 0.7, 0.25, 0.05};
  for (const LuGreParams& par : {LuGreParams{}, p2}) {
    LuGreFriction f(model, "j3", par);
    int checked = 0;
    for (int k = 0; k < 200; ++k) {
      const double v = uv(rng), z = uz(rng);
      if (std::abs(v) < 1e-3) continue;  // |v| is not differentiable at 0
      Eigen::VectorXd q = test::random_vector(rng, 3), qd = test::random_vector(rng, 3);
      qd[2] = v;
      Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
      Eigen::MatrixXd dQ = Eigen::MatrixXd::Constant(3, 3, 0.25);  // apply() adds
      double zd = 0;
      f.apply(0.0, q, qd, &z, Q, &zd, &dQ);
      Eigen::MatrixXd fd = Eigen::MatrixXd::Constant(3, 3, 0.25);
      const double h = 1e-7;
      for (int j = 0; j < 3; ++j) {
        Eigen::VectorXd qp = qd, qm = qd, Qp = Eigen::VectorXd::Zero(3), Qm = Eigen::VectorXd::Zero(3);
        qp[j] += h;
        qm[j] -= h;
        f.apply(0.0, q, qp, &z, Qp, &zd, nullptr);
        f.apply(0.0, q, qm, &z, Qm, &zd, nullptr);
        fd.col(j) += (Qp - Qm) / (2 * h);
      }
      // Truncation h²|Q'''|/6 with |Q'''| ≲ σ1σ0|z|/(g q̇S³)·… ~ 1e3 → 1e-12; rounding ε|Q|/h ~ 1e-10.
      EXPECT_TRUE(near(dQ, fd, 1e-7, 1e-8)) << "v = " << v << ", z = " << z;
      ++checked;
    }
    EXPECT_GT(checked, 150);
  }
}

TEST(LuGre, SteadyStateForConstantVelocity) {
  const Model model = three_joint_model();
  const LuGreParams par{0.3, 0.15, 40.0, 0.7, 0.25, 0.05};
  LuGreFriction f(model, "j1", par);
  for (double v : {0.02, -0.02, 0.3, -1.5}) {
    const double g = par.mu_k + (par.mu_s - par.mu_k) * std::exp(-(v / par.v_stribeck) * (v / par.v_stribeck));
    const double zss = g / par.sigma0 * (v > 0 ? 1 : -1);
    const double rate = par.sigma0 * std::abs(v) / g;  // ż = −rate (z − zss)
    Eigen::VectorXd q = Eigen::VectorXd::Zero(3), qd = Eigen::VectorXd::Zero(3);
    qd[0] = v;
    // Integrate ż alone with RK4; z(t) = zss + (z0 − zss) e^(−rate t).
    const double z0 = -0.5 * zss;
    OdeRhs rhs = [&](double t, const Eigen::VectorXd& z, Eigen::VectorXd& dz) {
      Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
      f.apply(t, q, qd, z.data(), Q, dz.data(), nullptr);
    };
    IntegratorOptions o;
    o.t1 = 40.0 / rate;  // e^(−40) ≈ 4e-18
    o.step = 0.01 / rate;
    Eigen::VectorXd z(1);
    z[0] = z0;
    double worst = 0;
    auto s = integrate(rhs, z, o, [&](double t, const Eigen::VectorXd& x) {
      worst = std::max(worst, std::abs(x[0] - (zss + (z0 - zss) * std::exp(-rate * t))));
      return true;
    });
    ASSERT_TRUE(s.ok()) << s.message;
    EXPECT_LT(worst, 1e-10 * std::abs(zss)) << "v = " << v;
    EXPECT_NEAR(z[0], zss, 1e-13 * std::abs(zss)) << "v = " << v;
    // At the steady state ż = 0 and the torque is −(g sgn v + σ2 v).
    Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
    double zd = 1;
    f.apply(0.0, q, qd, &zss, Q, &zd, nullptr);
    EXPECT_NEAR(zd, 0.0, 1e-15);
    EXPECT_NEAR(Q[0], -(g * (v > 0 ? 1 : -1) + par.sigma2 * v), 1e-15);
  }
}

TEST(FlexibleDrive, TorqueHasTheSignThatMakesTheJointFollowTheDrive) {
  const Model model = three_joint_model();
  FlexibleDriveParams p{1e4, 70.0};
  auto profile = cycloidal(2 * std::numbers::pi, 5.0);
  FlexibleDrive drive(model, "j1", p, profile);
  EXPECT_EQ(drive.joint(), 0);
  EXPECT_NE(drive.name().find("j1"), std::string::npos);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(3), qd = Eigen::VectorXd::Zero(3);
  const double t = 1.3;
  const TimeValue psi = profile->eval(t);
  // Joint behind the drive, moving slower: positive torque (pulls it forward).
  q[0] = psi.f - 0.01;
  qd[0] = psi.df - 0.2;
  EXPECT_GT(drive.torque(t, q, qd), 0.0);
  EXPECT_NEAR(drive.torque(t, q, qd), 1e4 * 0.01 + 70.0 * 0.2, 1e-9);
  // Joint ahead: negative torque.
  q[0] = psi.f + 0.003;
  qd[0] = psi.df;
  EXPECT_NEAR(drive.torque(t, q, qd), -30.0, 1e-9);
  // apply() adds the torque on its joint only and −d on the diagonal of ∂Q/∂q̇.
  Eigen::VectorXd Q = Eigen::VectorXd::Constant(3, 1.0);
  Eigen::MatrixXd dQ = Eigen::MatrixXd::Zero(3, 3);
  drive.apply(t, q, qd, nullptr, Q, nullptr, &dQ);
  EXPECT_NEAR(Q[0], 1.0 - 30.0, 1e-9);
  EXPECT_EQ(Q[1], 1.0);
  EXPECT_EQ(Q[2], 1.0);
  Eigen::MatrixXd dQ_expected = Eigen::MatrixXd::Zero(3, 3);
  dQ_expected(0, 0) = -70.0;
  EXPECT_TRUE(near(dQ, dQ_expected, 0, 0));
}

TEST(FlexibleDrive, SingleJointFollowsTheDisplacementProfile) {
  // A rotor about the vertical axis (gravity has no moment), J = 0.5 kg m², driven through the
  // flexible drive; no constraints (the reference dynamics reduce to M q̈ = Q).
  ModelDescription d;
  LinkSpec l;
  l.name = "rotor";
  l.inertia.mass = 2.0;
  l.inertia.I_com = Vec3(0.25, 0.25, 0.5).asDiagonal();
  d.add_link(l);
  const Model model = build_model(d);
  auto profile = cycloidal(2 * std::numbers::pi, 2.0);
  ForceSet forces;
  forces.add(std::make_shared<FlexibleDrive>(model, "rotor", FlexibleDriveParams{1e4, 70.0}, profile));
  ConstraintSet none;
  ReferenceDynamics rd(model, forces, none);
  Eigen::VectorXd x = rd.make_state(Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1));
  IntegratorOptions o;
  o.t1 = 3.0;
  o.step = 1e-4;
  double max_lag = 0, max_lead = 0;
  auto s = integrate([&](double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) { rd.derivative(t, xx, dx); }, x,
                     o, [&](double t, const Eigen::VectorXd& xx) {
                       const double e = profile->eval(t).f - xx[0];
                       max_lag = std::max(max_lag, e);
                       max_lead = std::max(max_lead, -e);
                       return true;
                     });
  ASSERT_TRUE(s.ok()) << s.message;
  // Following error ≈ J ψ̈ / s: |ψ̈| ≤ 2π·2π/4 ≈ 9.9 → ≈ 5e-4 rad.
  EXPECT_GT(max_lag, 1e-4);
  EXPECT_LT(max_lag, 1e-3);
  EXPECT_LT(max_lead, 1e-3);
  // Settled on the final value 2π (ζ = 0.5, ω_n ≈ 141 rad/s: fully decayed after 1 s at rest).
  EXPECT_NEAR(x[0], 2 * std::numbers::pi, 1e-9);
  EXPECT_NEAR(x[1], 0.0, 1e-8);
}

TEST(SimpleElements, DampingSpringEffort) {
  const Model model = three_joint_model();
  Eigen::VectorXd q(3), qd(3);
  q << 0.3, -0.2, 0.15;
  qd << 1.5, -0.5, 0.8;
  const double t = 0.4;
  {
    auto e = joint_damping(model, "j2", 3.0);
    Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
    Eigen::MatrixXd dQ = Eigen::MatrixXd::Zero(3, 3);
    e->apply(t, q, qd, nullptr, Q, nullptr, &dQ);
    EXPECT_EQ(Q, Eigen::Vector3d(0, 1.5, 0));
    EXPECT_EQ(dQ(1, 1), -3.0);
    EXPECT_EQ(dQ.cwiseAbs().sum(), 3.0);
    EXPECT_EQ(e->num_states(), 0);
  }
  {
    auto e = joint_spring(model, "j3", 200.0, 0.1);
    Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
    Eigen::MatrixXd dQ = Eigen::MatrixXd::Zero(3, 3);
    e->apply(t, q, qd, nullptr, Q, nullptr, &dQ);
    EXPECT_NEAR(Q[2], -200.0 * 0.05, 1e-13);
    EXPECT_EQ(Q[0], 0.0);
    EXPECT_EQ(dQ.cwiseAbs().sum(), 0.0);  // no velocity dependence
  }
  {
    auto e = joint_effort(model, "j1", sinusoid(2.0, 3.0));
    Eigen::VectorXd Q = Eigen::VectorXd::Zero(3);
    e->apply(t, q, qd, nullptr, Q, nullptr, nullptr);
    EXPECT_NEAR(Q[0], 2.0 * std::sin(1.2), 1e-15);
    EXPECT_EQ(Q[1], 0.0);
  }
}

TEST(ForceSet, SumsElementsConcatenatesStatesAndOverwritesOutputs) {
  const Model model = three_joint_model();
  ForceSet fs;
  fs.add(joint_damping(model, "j1", 2.0));
  fs.add(std::make_shared<LuGreFriction>(model, "j1", LuGreParams{}));
  fs.add(joint_spring(model, "j2", 5.0));
  fs.add(std::make_shared<LuGreFriction>(model, "j3", LuGreParams{0.1, 0.2, 1.0, 0.02, 0.0, 0.001}));
  fs.add(joint_effort(model, "j3", constant(-4.0)));
  EXPECT_EQ(fs.num_states(), 2);
  EXPECT_EQ(fs.state_offset(0), 0);
  EXPECT_EQ(fs.state_offset(1), 0);
  EXPECT_EQ(fs.state_offset(2), 1);
  EXPECT_EQ(fs.state_offset(3), 1);
  EXPECT_EQ(fs.state_offset(4), 2);
  EXPECT_EQ(fs.state_names(), (std::vector<std::string>{"z_j1", "z_j3"}));

  Eigen::VectorXd q(3), qd(3);
  q << 0.3, -0.2, 0.15;
  qd << 0.4, -0.5, 0.002;
  const double z[2] = {0.01, -0.0003};
  double zdot[2] = {kNaN, kNaN};
  Eigen::VectorXd Q = Eigen::VectorXd::Constant(3, 123.0);  // must be overwritten
  Eigen::MatrixXd dQ = Eigen::MatrixXd::Constant(3, 3, 7.0);
  fs.evaluate(0.5, q, qd, z, Q, zdot, &dQ);
  const LuGreHand h1 = lugre_by_hand(LuGreParams{}, 0.4, 0.01);
  const LuGreHand h3 = lugre_by_hand(LuGreParams{0.1, 0.2, 1.0, 0.02, 0.0, 0.001}, 0.002, -0.0003);
  EXPECT_NEAR(zdot[0], h1.zdot, 1e-15);
  EXPECT_NEAR(zdot[1], h3.zdot, 1e-15);
  EXPECT_NEAR(Q[0], -2.0 * 0.4 + h1.tau, 1e-14);
  EXPECT_NEAR(Q[1], -5.0 * -0.2, 1e-14);
  EXPECT_NEAR(Q[2], h3.tau - 4.0, 1e-14);
  EXPECT_EQ(dQ(0, 1), 0.0);  // overwritten, not accumulated
  EXPECT_EQ(dQ(1, 1), 0.0);
  EXPECT_LT(dQ(0, 0), -2.0);
  // element_force: each element alone, summing to Q.
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(3);
  for (int k = 0; k < 5; ++k) sum += fs.element_force(k, 0.5, q, qd, z);
  EXPECT_TRUE(near(sum, Q, 1e-15, 1e-15));
  EXPECT_NEAR(fs.element_force(0, 0.5, q, qd, z)[0], -0.8, 1e-15);
  EXPECT_NEAR(fs.element_force(3, 0.5, q, qd, z)[2], h3.tau, 1e-15);
}

TEST(ForceElements, BadParametersThrowWithMessages) {
  const Model model = three_joint_model();
  expect_error_mentioning([&] { joint_damping(model, "j1", -1.0); }, {"damping", "j1", ">= 0"});
  expect_error_mentioning([&] { joint_damping(model, "j1", kNaN); }, {"damping"});
  expect_error_mentioning([&] { joint_damping(model, "jj2", 1.0); }, {"jj2", "did you mean 'j2'"});
  expect_error_mentioning([&] { joint_spring(model, "j2", -3.0); }, {"stiffness", "j2"});
  expect_error_mentioning([&] { joint_spring(model, "j2", 3.0, kNaN); }, {"rest"});
  expect_error_mentioning([&] { joint_effort(model, "j3", nullptr); }, {"time function"});
  expect_error_mentioning([&] { joint_effort(model, "elbow", constant(1.0)); }, {"elbow"});
  expect_error_mentioning([&] { FlexibleDrive(model, "j1", {-1.0, 70.0}, constant(0.0)); }, {"stiffness"});
  expect_error_mentioning([&] { FlexibleDrive(model, "j1", {1e4, kNaN}, constant(0.0)); }, {"damping"});
  expect_error_mentioning([&] { FlexibleDrive(model, "j1", {1e4, 70.0}, nullptr); }, {"profile"});
  auto lugre = [&](LuGreParams p) { LuGreFriction(model, "j1", p); };
  LuGreParams p;
  p.mu_s = 0.0;
  expect_error_mentioning([&] { lugre(p); }, {"mu_s", "j1"});
  p = {};
  p.mu_k = -0.2;
  expect_error_mentioning([&] { lugre(p); }, {"mu_k"});
  p = {};
  p.sigma0 = -1;
  expect_error_mentioning([&] { lugre(p); }, {"sigma0"});
  p = {};
  p.sigma1 = kNaN;
  expect_error_mentioning([&] { lugre(p); }, {"sigma1"});
  p = {};
  p.sigma2 = -0.1;
  expect_error_mentioning([&] { lugre(p); }, {"sigma2"});
  p = {};
  p.v_stribeck = 0.0;
  expect_error_mentioning([&] { lugre(p); }, {"Stribeck"});
  ForceSet fs;
  expect_error_mentioning([&] { fs.add(nullptr); }, {"force element"});
}
