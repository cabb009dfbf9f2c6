// The example scenarios (examples/*/*.yaml): each is loaded with the scenario loader, planned
// with the reference dynamics, and checked against a physical property computed independently
// here (geometry, kinematics, closed-form solutions, momentum and energy balances), not against
// numbers recorded from an earlier run. The paper scenario file must reproduce the built-in
// paper example, and every example must also run through the refdyn command line.
#include "refdyn/simulate/closed_loop.hpp"
#include "refdyn/simulate/plan.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

using namespace refdyn;
namespace fs = std::filesystem;

namespace {

constexpr double kPi = std::numbers::pi;

std::string source_path(const std::string& rel) { return std::string(REFDYN_SOURCE_DIR) + "/" + rel; }

/// A scenario planned the way `refdyn plan` does it.
struct Planned {
  std::unique_ptr<Problem> sc;
  std::unique_ptr<ReferenceDynamics> rd;
  Plan plan;
  int n = 0;
  Eigen::VectorXd q(size_t k) const { return plan.x[k].head(n); }
  Eigen::VectorXd qd(size_t k) const { return plan.x[k].segment(n, n); }
  double param(const std::string& name) const {
    const auto it = sc->parameters.find(name);
    if (it == sc->parameters.end()) throw std::runtime_error("scenario has no parameter '" + name + "'");
    return it->second;
  }
  int row(const std::string& name) const {
    for (int r = 0; r < sc->constraints.rows(); ++r)
      if (sc->constraints.row_name(r) == name) return r;
    throw std::runtime_error("scenario has no constraint row '" + name + "'");
  }
};

Planned plan_scenario(std::unique_ptr<Problem> sc) {
  Planned p;
  p.sc = std::move(sc);
  Problem& s = *p.sc;
  p.n = s.model.nq;
  if (s.is_jerk_problem()) {  // its own planner (JerkDynamics); no ReferenceDynamics
    p.plan = plan_problem(s, *s.make_planner());
    return p;
  }
  p.rd = std::make_unique<ReferenceDynamics>(s.model, s.forces, s.constraints, s.options);
  p.plan = plan_motion(*p.rd, p.rd->make_state(s.q0, s.qd0), {s.integrator, s.residual_from});
  return p;
}

Planned plan_file(const std::string& rel) { return plan_scenario(io::load_problem(source_path(rel))); }

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Angle difference wrapped to (−π, π].
double wrap(double a) { return std::remainder(a, 2 * kPi); }

/// ∫ f dt over the samples with t in [ta, tb] (trapezoid on the plan's grid).
double integrate_samples(const std::vector<double>& t, const std::vector<double>& f, double ta, double tb) {
  double s = 0;
  for (size_t k = 1; k < t.size(); ++k)
    if (t[k - 1] >= ta - 1e-9 && t[k] <= tb + 1e-9) s += 0.5 * (t[k] - t[k - 1]) * (f[k] + f[k - 1]);
  return s;
}

void report(const char* example, const char* what, double value) {
  std::printf("[ measured ] %-18s %-48s %.3e\n", example, what, value);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// 1. Planar 2R arm, end effector on a circle at constant speed (n − m = 0).
TEST(Examples, Planar2RCircleUniformCircularMotion) {
  Planned p = plan_file("examples/planar_2r_circle/planar_2r_circle.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const Model& m = p.sc->model;
  ASSERT_EQ(m.nq, 2);
  ASSERT_EQ(p.sc->constraints.rows(), 2);
  EXPECT_TRUE(p.rd->independent().empty());  // no independent coordinate is left
  const double cx = p.param("cx"), cy = p.param("cy"), R = p.param("R"), v0 = p.param("v0"), Tp = p.param("Tp");
  ASSERT_NEAR(v0 * Tp, 2 * kPi * R, 1e-12);
  const int E = m.point_index("E");
  Data data(m);
  double err_r = 0, err_v = 0, err_angle = 0, err_acc = 0;
  double theta0 = 0, prev = 0, unwrapped = 0;
  std::vector<double> power;
  Eigen::VectorXd dx(p.rd->state_size());
  for (size_t k = 0; k < p.plan.t.size(); ++k) {
    const double t = p.plan.t[k];
    const Eigen::VectorXd q = p.q(k), qd = p.qd(k);
    forward_kinematics(m, data, q);
    const Vec3 r = point_position(m, data, E);
    point_jacobian(m, data, E);
    const Vec3 v = data.Jp * qd;
    const Vec3 a = data.Jp * p.plan.qdd[k] + point_drift(m, data, E, qd).drift;
    const Vec3 rel(r.x() - cx, r.y() - cy, 0.0);
    err_r = std::max(err_r, std::abs(rel.norm() - R));
    err_v = std::max(err_v, std::abs(v.norm() - v0));
    // Uniform circular motion: the acceleration is centripetal, v0²/R towards the centre.
    err_acc = std::max(err_acc, (a + (v0 * v0 / (R * R)) * rel).norm());
    // The angle of E about C advances at v0/R (counter-clockwise).
    const double th = std::atan2(rel.y(), rel.x());
    if (k == 0) theta0 = prev = unwrapped = th;
    unwrapped += wrap(th - prev);
    prev = th;
    err_angle = std::max(err_angle, std::abs(unwrapped - theta0 - v0 / R * t));
    p.rd->derivative(t, p.plan.x[k], dx);
    power.push_back(p.rd->constraint_force().dot(qd));  // power of the joint torques realizing the task
  }
  report("planar_2r_circle", "max ||E - C| - R| [m]", err_r);
  report("planar_2r_circle", "max ||v_E| - v0| [m/s]", err_v);
  report("planar_2r_circle", "max |angle - v0 t/R| [rad]", err_angle);
  report("planar_2r_circle", "max |a_E - centripetal| [m/s^2]", err_acc);
  EXPECT_LT(err_r, 1e-6);
  EXPECT_LT(err_v, 1e-6);
  EXPECT_LT(err_angle, 1e-6);
  // q̈ of the plan carries the Baumgarte term −2αΦ̇ − β²Φ acting on the RK4 truncation residual
  // (|Φ̇| ~ 3e-9 m²/s at h = 1e-3, shrinking as h⁴): ~1e-6 m/s² against v0²/R = 1.5 m/s².
  EXPECT_LT(err_acc, 1e-5);
  // The motion is Tp-periodic and the only other force is gravity (conservative): the torques
  // do no net work over one turn, W = Δ(T + V) = 0.
  double scale = 0;
  for (double w : power) scale = std::max(scale, std::abs(w));
  for (double t0 = 0; t0 + Tp <= p.sc->integrator.t1 + 1e-9; t0 += Tp) {
    const double W = integrate_samples(p.plan.t, power, t0, t0 + Tp);
    report("planar_2r_circle", "|work of the torques over one turn| / (P_max Tp)", std::abs(W) / (scale * Tp));
    EXPECT_LT(std::abs(W), 1e-6 * scale * Tp);
  }
}

TEST(Examples, Planar2RCircleAutomaticPartitionGivesTheSamePlan) {
  // `partition: auto` and `partition: {independent: []}` describe the same (empty) choice.
  const std::string path = source_path("examples/planar_2r_circle/planar_2r_circle.yaml");
  std::string text = read_text(path);
  const std::string from = "independent: []";
  const size_t pos = text.find(from);
  ASSERT_NE(pos, std::string::npos);
  text.replace(pos, from.size(), "independent: auto");
  Planned a = plan_scenario(io::parse_problem(text, path));
  Planned b = plan_file("examples/planar_2r_circle/planar_2r_circle.yaml");
  ASSERT_TRUE(a.plan.summary.ok()) << a.plan.summary.message;
  ASSERT_EQ(a.plan.x.size(), b.plan.x.size());
  EXPECT_TRUE(test::near(a.plan.x.back(), b.plan.x.back(), 0.0, 1e-12));
}

// ---------------------------------------------------------------------------------------------
// 2. Unicycle / knife edge at constant forward speed and yaw rate: a circle of radius v0/ω.
TEST(Examples, UnicycleRunsOnACircle) {
  Planned p = plan_file("examples/unicycle/unicycle.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const Model& m = p.sc->model;
  const int ix = m.joint_index("x"), iy = m.joint_index("y"), ith = m.joint_index("theta");
  const double v0 = p.param("v0"), omega = p.param("omega"), mass = m.total_mass();
  ASSERT_EQ(p.rd->independent(), std::vector<int>{ith});
  // Start at the origin heading along +x, turning left: the centre is (0, v0/ω).
  const double Rc = v0 / omega;
  ASSERT_NEAR(p.q(0)[ix], 0.0, 0.0);
  ASSERT_NEAR(p.q(0)[iy], 0.0, 0.0);
  ASSERT_NEAR(p.q(0)[ith], 0.0, 0.0);
  const int P = m.point_index("P");
  Data data(m);
  double err_lat = 0, err_fwd = 0, err_rate = 0, err_radius = 0, err_centre = 0, err_kappa = 0, err_force = 0;
  double max_tangential_force = 0;
  Eigen::VectorXd dx(p.rd->state_size());
  for (size_t k = 0; k < p.plan.t.size(); ++k) {
    const Eigen::VectorXd q = p.q(k), qd = p.qd(k), qdd = p.plan.qdd[k];
    const double th = q[ith], c = std::cos(th), s = std::sin(th);
    err_lat = std::max(err_lat, std::abs(-s * qd[ix] + c * qd[iy]));
    err_fwd = std::max(err_fwd, std::abs(c * qd[ix] + s * qd[iy] - v0));
    // No torque about the vertical axis is left over (the steering torque balances the damping
    // and the contact forces act on the axis): the yaw rate stays ω.
    err_rate = std::max(err_rate, std::abs(qd[ith] - omega));
    forward_kinematics(m, data, q);
    const Vec3 r = point_position(m, data, P);
    const Eigen::Vector2d rel(r.x(), r.y() - Rc);
    err_radius = std::max(err_radius, std::abs(rel.norm() - Rc));
    // Centre of curvature from the state: P + (|v|/θ̇) n, n the left normal of the heading.
    const double speed = std::hypot(qd[ix], qd[iy]);
    const Eigen::Vector2d centre(r.x() - speed / qd[ith] * s, r.y() + speed / qd[ith] * c);
    err_centre = std::max(err_centre, (centre - Eigen::Vector2d(0, Rc)).norm());
    // Curvature of the path: κ = (ẋÿ − ẏẍ)/|v|³ = ω/v0.
    const double kappa = (qd[ix] * qdd[iy] - qd[iy] * qdd[ix]) / (speed * speed * speed);
    err_kappa = std::max(err_kappa, std::abs(kappa - omega / v0));
    // The blade's lateral reaction is the centripetal force m v0 ω, towards the centre; no
    // tangential force is needed to keep the speed (nothing resists the rolling).
    p.rd->derivative(p.plan.t[k], p.plan.x[k], dx);
    const Eigen::Vector2d F(p.rd->constraint_force()[ix], p.rd->constraint_force()[iy]);
    err_force = std::max(err_force, std::abs(F.dot(-rel.normalized()) - mass * v0 * omega));
    max_tangential_force = std::max(max_tangential_force, std::abs(F.dot(Eigen::Vector2d(c, s))));
  }
  report("unicycle", "max |lateral velocity| [m/s]", err_lat);
  report("unicycle", "max |forward speed - v0| [m/s]", err_fwd);
  report("unicycle", "max |yaw rate - omega| [rad/s]", err_rate);
  report("unicycle", "max ||P - centre| - v0/omega| [m]", err_radius);
  report("unicycle", "max |centre of curvature - (0, v0/omega)| [m]", err_centre);
  report("unicycle", "max |curvature - omega/v0| [1/m]", err_kappa);
  report("unicycle", "max |radial reaction - m v0 omega| [N]", err_force);
  report("unicycle", "max |tangential reaction| [N]", max_tangential_force);
  EXPECT_LT(err_lat, 1e-6);
  EXPECT_LT(err_fwd, 1e-6);
  EXPECT_LT(err_rate, 1e-9);
  EXPECT_LT(err_radius, 1e-6);
  EXPECT_LT(err_centre, 1e-6);
  EXPECT_LT(err_kappa, 1e-6);
  EXPECT_LT(err_force, 1e-6 * mass * v0 * omega);
  EXPECT_LT(max_tangential_force, 1e-6 * mass * v0 * omega);
  // More than one full turn was planned.
  EXPECT_GT(p.plan.t.back() * omega, 2 * kPi);
}

// ---------------------------------------------------------------------------------------------
// 3. Four-bar linkage: loop closure and the closed-form position solution.
TEST(Examples, FourBarFollowsTheClosedFormPositionSolution) {
  Planned p = plan_file("examples/four_bar/four_bar.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const Model& m = p.sc->model;
  ASSERT_EQ(m.nq, 3);
  const double a = p.param("a"), b = p.param("b"), c = p.param("c"), d = p.param("d");
  const double omega = p.param("omega"), th0 = p.param("th0");
  // Grashof crank-rocker: the crank is the shortest link and s + l <= p + q.
  ASSERT_LT(a, std::min({b, c, d}));
  ASSERT_LE(a + std::max({b, c, d}), b + c + d - std::max({b, c, d}));
  const int T = m.point_index("T"), D = m.point_index("D"), B = m.point_index("B"), C = m.point_index("C");
  const int loop0 = p.row("loop[0]"), loop1 = p.row("loop[1]");
  Data data(m);
  // Closed form: C is on the circle of radius b about B and on the circle of radius c about
  // D = (d, 0); the branch (side of the line B→D) is the one the linkage was assembled in.
  auto closed_form_C = [&](double crank, double side) {
    const Eigen::Vector2d Bp(a * std::cos(crank), a * std::sin(crank)), Dp(d, 0);
    const double e = (Dp - Bp).norm();
    const Eigen::Vector2d u = (Dp - Bp) / e, nrm(-u.y(), u.x());
    const double along = (b * b - c * c + e * e) / (2 * e);
    return Eigen::Vector2d(Bp + along * u + side * std::sqrt(b * b - along * along) * nrm);
  };
  double side = 0;
  double err_loop = 0, err_loop_rows = 0, err_crank = 0, err_rocker = 0, err_coupler = 0;
  bool finite = true;
  std::vector<double> power;
  Eigen::VectorXd dx(p.rd->state_size());
  for (size_t k = 0; k < p.plan.t.size(); ++k) {
    const double t = p.plan.t[k];
    const Eigen::VectorXd q = p.q(k), qd = p.qd(k);
    forward_kinematics(m, data, q);
    const Vec3 rT = point_position(m, data, T), rD = point_position(m, data, D);
    const Vec3 rB = point_position(m, data, B), rC = point_position(m, data, C);
    err_loop = std::max(err_loop, (rT - rD).head<2>().norm());
    if (k == 0) {
      const Eigen::Vector2d BD = (rD - rB).head<2>(), BC = (rC - rB).head<2>();
      side = (BD.x() * BC.y() - BD.y() * BC.x()) > 0 ? 1.0 : -1.0;
    }
    const double crank = th0 + omega * t;  // the prescribed crank angle
    err_crank = std::max(err_crank, std::abs(q[0] - crank));
    const Eigen::Vector2d Ccf = closed_form_C(crank, side);
    // Absolute link angles of the chain: coupler q1 + q2, rocker (D→C) q1 + q2 + q3 + π.
    const double coupler = q[0] + q[1], rocker = q[0] + q[1] + q[2] + kPi;
    const Eigen::Vector2d Bcf(a * std::cos(crank), a * std::sin(crank));
    err_coupler = std::max(err_coupler, std::abs(wrap(coupler - std::atan2(Ccf.y() - Bcf.y(), Ccf.x() - Bcf.x()))));
    err_rocker = std::max(err_rocker, std::abs(wrap(rocker - std::atan2(Ccf.y(), Ccf.x() - d))));
    p.rd->derivative(t, p.plan.x[k], dx);
    const ConstraintEval& ev = p.rd->constraints();
    err_loop_rows = std::max({err_loop_rows, std::abs(ev.phi[loop0]), std::abs(ev.phi[loop1])});
    finite = finite && p.rd->constraint_force().allFinite() && p.rd->lambda().allFinite();
    power.push_back(p.rd->constraint_force().dot(qd));  // the drive's power (the loop is workless)
  }
  report("four_bar", "max |r_T - r_D| (loop closure, FK) [m]", err_loop);
  report("four_bar", "max |Phi_loop| [m]", err_loop_rows);
  report("four_bar", "max |crank - (th0 + omega t)| [rad]", err_crank);
  report("four_bar", "max |rocker - closed form| [rad]", err_rocker);
  report("four_bar", "max |coupler - closed form| [rad]", err_coupler);
  EXPECT_LT(err_loop, 1e-8);
  EXPECT_LT(err_loop_rows, 1e-8);
  EXPECT_LT(err_crank, 1e-8);
  EXPECT_LT(err_rocker, 1e-6);
  EXPECT_LT(err_coupler, 1e-6);
  EXPECT_TRUE(finite);
  // Conservative system driven periodically: the drive does no net work per crank turn.
  const double Tc = 2 * kPi / omega;
  double scale = 0;
  for (double w : power) scale = std::max(scale, std::abs(w));
  int turns = 0;
  for (double t0 = 0; t0 + Tc <= p.sc->integrator.t1 + 1e-9; t0 += Tc, ++turns) {
    const double W = integrate_samples(p.plan.t, power, t0, t0 + Tc);
    report("four_bar", "|drive work over one crank turn| / (P_max Tc)", std::abs(W) / (scale * Tc));
    EXPECT_LT(std::abs(W), 1e-6 * scale * Tc);
  }
  EXPECT_GE(turns, 1);
}

// ---------------------------------------------------------------------------------------------
// 4. The 7-DOF URDF arm: tool point on a vertical line, height z_a(t), four redundant DOF.
TEST(Examples, UrdfArmKeepsTheToolOnTheLine) {
  Planned p = plan_file("examples/urdf_arm_line/urdf_arm_line.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const Model& m = p.sc->model;
  ASSERT_EQ(m.nq, 7);
  ASSERT_EQ(p.sc->constraints.rows(), 3);
  EXPECT_EQ(p.rd->independent().size(), 4u);
  const double x0 = p.param("x0"), y0 = p.param("y0"), z0 = p.param("z0"), dz = p.param("dz"), Tz = p.param("T");
  auto z_a = [&](double t) { return z0 + dz * (1 - std::cos(2 * kPi * t / Tz)) / 2; };
  const int tool = m.point_index("tool");
  const double t_settled = p.sc->residual_from;
  Data data(m);
  double err_line = 0, err_height = 0, err_workless = 0;
  Eigen::VectorXd dx(p.rd->state_size());
  for (size_t k = 0; k < p.plan.t.size(); ++k) {
    const double t = p.plan.t[k];
    forward_kinematics(m, data, p.q(k));
    const Vec3 r = point_position(m, data, tool);
    if (t >= t_settled - 1e-12) {
      err_line = std::max({err_line, std::abs(r.x() - x0), std::abs(r.y() - y0)});
      err_height = std::max(err_height, std::abs(r.z() - z_a(t)));
    }
    // Ideal constraints: the joint efforts that realize the task lie in the row space of A, so
    // they do no work on the (unactuated) redundant motions A q̇ = 0.
    p.rd->derivative(t, p.plan.x[k], dx);
    const Eigen::MatrixXd& A = p.rd->constraints().A;
    const Eigen::VectorXd& Qc = p.rd->constraint_force();
    const Eigen::MatrixXd At = A.transpose();
    const Eigen::VectorXd in_row_space = At * At.colPivHouseholderQr().solve(Qc);
    err_workless = std::max(err_workless, (Qc - in_row_space).norm() / std::max(1.0, Qc.norm()));
  }
  report("urdf_arm_line", "max |x - x0|, |y - y0| for t >= 0.5 s [m]", err_line);
  report("urdf_arm_line", "max |z - z_a(t)| for t >= 0.5 s [m]", err_height);
  report("urdf_arm_line", "max |Q_c off the row space of A| / |Q_c|", err_workless);
  EXPECT_LT(err_line, 1e-8);
  EXPECT_LT(err_height, 1e-8);
  EXPECT_LT(err_workless, 1e-9);
  // The redundant motion is damped: after the transient it is entrained by the T-periodic task,
  // q(t) = q(t − T), and it stays bounded (well inside the URDF joint limits).
  const size_t per = static_cast<size_t>(std::lround(Tz / p.sc->integrator.step));
  ASSERT_GE(p.plan.t.size(), 3 * per + 1);
  double err_periodic = 0, err_periodic_first = 0;
  for (size_t k = 2 * per; k < p.plan.t.size(); ++k)
    err_periodic = std::max(err_periodic, (p.q(k) - p.q(k - per)).cwiseAbs().maxCoeff());
  for (size_t k = per; k < 2 * per; ++k)
    err_periodic_first = std::max(err_periodic_first, (p.q(k) - p.q(k - per)).cwiseAbs().maxCoeff());
  report("urdf_arm_line", "max |q(t) - q(t - T)|, first period [rad]", err_periodic_first);
  report("urdf_arm_line", "max |q(t) - q(t - T)|, t in [2T, 3T] [rad]", err_periodic);
  EXPECT_LT(err_periodic, 1e-4);
  EXPECT_LT(err_periodic, 0.1 * err_periodic_first);  // the transient decays
  for (size_t k = 0; k < p.plan.t.size(); ++k)
    for (int j = 0; j < m.nq; ++j) {
      ASSERT_GT(p.q(k)[j], m.limits[j].lower) << m.joint_name[j] << " at t = " << p.plan.t[k];
      ASSERT_LT(p.q(k)[j], m.limits[j].upper) << m.joint_name[j] << " at t = " << p.plan.t[k];
    }
}

// An acceleration-level (p = 2) programmed constraint: a cup on a tray at E must not slide,
// (a_E − g)·u(θ) = 0, u = (cos θ, sin θ), θ = q1 + q2 + φ. Checked from the recorded motion
// alone: a_E by central differences of the forward kinematics of the recorded q (error
// ~h²/12 |d⁴r/dt⁴|), against the tangential specific force a level tray would have felt; and
// the ideal reaction acts as a force along the tray at E: Q_c ∥ C_Eᵀ u.
TEST(Examples, WaiterTrayKeepsTheCupFromSliding) {
  Planned p = plan_file("examples/waiter_tray/waiter_tray.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const Model& m = p.sc->model;
  ASSERT_EQ(p.sc->constraints.row_order(0), 2);
  const double g = p.param("g"), phi = p.param("phi"), h = p.sc->integrator.step;
  const int E = m.point_index("E");
  Data data(m);
  auto tip = [&](size_t k) {
    forward_kinematics(m, data, p.q(k));
    return point_position(m, data, E);
  };
  double err_slide = 0, level_tray = 0, err_reaction = 0, peak_qc = 0;
  Eigen::VectorXd dx(p.rd->state_size());
  for (size_t k = 1; k + 1 < p.plan.t.size(); ++k) {
    const Vec3 a = (tip(k + 1) - 2 * tip(k) + tip(k - 1)) / (h * h);
    const double th = p.q(k)[0] + p.q(k)[1] + phi;
    err_slide = std::max(err_slide, std::abs(a.x() * std::cos(th) + (a.y() + g) * std::sin(th)));
    level_tray = std::max(level_tray, std::abs(a.x()));
    if (k % 50) continue;
    p.rd->derivative(p.plan.t[k], p.plan.x[k], dx);
    forward_kinematics(m, data, p.q(k));
    point_jacobian(m, data, E);
    const Eigen::Vector2d b = data.Jp.topRows(2).transpose() * Eigen::Vector2d(std::cos(th), std::sin(th));
    const Eigen::VectorXd& Qc = p.rd->constraint_force();
    err_reaction = std::max(err_reaction, std::abs(Qc[0] * b[1] - Qc[1] * b[0]) / (b.norm() * std::max(1.0, Qc.norm())));
    peak_qc = std::max(peak_qc, Qc.norm());
  }
  report("waiter_tray", "max |(a_E - g).u| from the recorded motion [m/s^2]", err_slide);
  report("waiter_tray", "max |a_E,x|: what a level tray would feel [m/s^2]", level_tray);
  report("waiter_tray", "max |Q_c off C_E^T u| / |Q_c|", err_reaction);
  EXPECT_LT(err_slide, 1e-3);
  EXPECT_GT(level_tray, 1.0);
  EXPECT_LT(err_reaction, 1e-9);
  EXPECT_GT(peak_qc, 0.1);  // the forearm is no point mass: the elbow must act
}

// A URDF <mimic> joint becomes the material constraint mimic_<joint> (joint_coupling). A
// three-link arm swinging under gravity with its third joint geared to the second: the
// coupling holds along the plan, and since the coupling is ideal and scleronomic and there is
// no damping, the energy T + V is conserved.
TEST(Examples, UrdfMimicJointIsAnIdealCoupling) {
  const fs::path dir = fs::temp_directory_path() / ("refdyn_mimic_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto inertial = [](double m, double len) {
    std::ostringstream os;
    os << "<inertial><origin xyz=\"" << len / 2 << " 0 0\" rpy=\"0 0 0\"/><mass value=\"" << m
       << "\"/><inertia ixx=\"0.001\" ixy=\"0\" ixz=\"0\" iyy=\"" << m * len * len / 12 << "\" iyz=\"0\" izz=\""
       << m * len * len / 12 << "\"/></inertial>";
    return os.str();
  };
  auto jnt = [](const char* name, const char* parent, const char* child, double x, const char* extra) {
    return std::string("<joint name=\"") + name + "\" type=\"continuous\"><parent link=\"" + parent +
           "\"/><child link=\"" + child + "\"/><origin xyz=\"" + std::to_string(x) +
           " 0 0\" rpy=\"0 0 0\"/><axis xyz=\"0 1 0\"/>" + extra + "</joint>\n";
  };
  {
    std::ofstream u(dir / "arm3.urdf");
    u << "<?xml version=\"1.0\"?>\n<robot name=\"arm3\">\n<link name=\"base\"/>\n"
      << "<link name=\"l1\">" << inertial(2.0, 0.5) << "</link>\n<link name=\"l2\">" << inertial(1.5, 0.4)
      << "</link>\n<link name=\"l3\">" << inertial(1.0, 0.3) << "</link>\n"
      << jnt("j1", "base", "l1", 0.0, "") << jnt("j2", "l1", "l2", 0.5, "")
      << jnt("j3", "l2", "l3", 0.4, "<mimic joint=\"j2\" multiplier=\"0.5\" offset=\"0.1\"/>") << "</robot>\n";
    // The same arm without <mimic>, the coupling written as a ready-made constraint kind.
    std::ofstream uf(dir / "arm3_free.urdf");
    uf << "<?xml version=\"1.0\"?>\n<robot name=\"arm3\">\n<link name=\"base\"/>\n"
       << "<link name=\"l1\">" << inertial(2.0, 0.5) << "</link>\n<link name=\"l2\">" << inertial(1.5, 0.4)
       << "</link>\n<link name=\"l3\">" << inertial(1.0, 0.3) << "</link>\n"
       << jnt("j1", "base", "l1", 0.0, "") << jnt("j2", "l1", "l2", 0.5, "") << jnt("j3", "l2", "l3", 0.4, "")
       << "</robot>\n";
    std::ofstream yk(dir / "kind.yaml");
    yk << "name: mimic\nmodel:\n  urdf: {file: arm3_free.urdf}\n  gravity: [0, 0, -9.81]\n"
          "constraints:\n  - {name: gear, kind: joint_coupling, joint: j3, leader: j2, ratio: 0.5, offset: 0.1}\n"
          "partition:\n  independent: auto\n"
          "initial:\n  q: {j1: 0.3, j2: -0.4, j3: 0.5*(-0.4) + 0.1}\n  qd: {j1: 0.5, j2: 1.0, j3: 0.5}\n"
          "integrator: {method: rk4, step: 1e-3, t0: 0, t1: 2}\n";
    for (const char* h : {"1e-3", "5e-4"}) {
      std::ofstream y(dir / ("mimic_" + std::string(h) + ".yaml"));
      y << "name: mimic\nmodel:\n  urdf: {file: arm3.urdf}\n  gravity: [0, 0, -9.81]\n"
           "partition:\n  independent: auto\n"
           "initial:\n  q: {j1: 0.3, j2: -0.4, j3: 0.5*(-0.4) + 0.1}\n  qd: {j1: 0.5, j2: 1.0, j3: 0.5}\n"
           "integrator: {method: rk4, step: " << h << ", t0: 0, t1: 2}\n";
    }
  }
  Planned p = plan_scenario(io::load_problem((dir / "mimic_1e-3.yaml").string()));
  Planned fine = plan_scenario(io::load_problem((dir / "mimic_5e-4.yaml").string()));
  Planned kind = plan_scenario(io::load_problem((dir / "kind.yaml").string()));
  fs::remove_all(dir);
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  ASSERT_TRUE(fine.plan.summary.ok()) << fine.plan.summary.message;
  const Model& m = p.sc->model;
  ASSERT_EQ(m.nq, 3);
  ASSERT_EQ(p.sc->constraints.rows(), 1);
  EXPECT_EQ(p.sc->constraints.row_name(0), "mimic_j3");
  Data data(m);
  double E0 = 0;
  auto check = [&](const Planned& run, double& worst_coupling, double& worst_energy, double& swing) {
    worst_coupling = worst_energy = swing = 0;
    for (size_t k = 0; k < run.plan.t.size(); ++k) {
      const Eigen::VectorXd q = run.q(k), qd = run.qd(k);
      worst_coupling = std::max(worst_coupling, std::abs(q[2] - 0.5 * q[1] - 0.1));
      const double E = kinetic_energy(m, data, q, qd) + potential_energy(m, data, q);
      if (k == 0) E0 = E;
      worst_energy = std::max(worst_energy, std::abs(E - E0));
      swing = std::max(swing, std::abs(q[0] - run.q(0)[0]));
    }
  };
  double coupling, energy, swing, coupling_fine, energy_fine, swing_fine;
  check(p, coupling, energy, swing);
  check(fine, coupling_fine, energy_fine, swing_fine);
  report("urdf_mimic", "max |q3 - 0.5 q2 - 0.1| [rad]", std::max(coupling, coupling_fine));
  report("urdf_mimic", "max |E - E0| [J], h = 1e-3", energy);
  report("urdf_mimic", "max |E - E0| [J], h = 5e-4", energy_fine);
  EXPECT_GT(swing, 0.5);  // it really moves
  EXPECT_LT(std::max(coupling, coupling_fine), 1e-12);
  EXPECT_LT(energy, 1e-7 * std::abs(E0));
  EXPECT_GT(energy / energy_fine, 10.0) << "energy drift does not converge at RK4's order";
  // The scenario kind joint_coupling gives the same motion as the URDF <mimic>.
  ASSERT_TRUE(kind.plan.summary.ok()) << kind.plan.summary.message;
  ASSERT_EQ(kind.plan.x.size(), p.plan.x.size());
  EXPECT_EQ(kind.sc->constraints.constraints()[0]->origin, ConstraintOrigin::Material);
  for (size_t k = 0; k < p.plan.x.size(); ++k) ASSERT_TRUE(test::near(kind.plan.x[k], p.plan.x[k], 1e-12, 1e-12)) << k;
}

// ---------------------------------------------------------------------------------------------
// 5. The paper scenario file reproduces the built-in paper example.
TEST(Examples, PaperScenarioFileMatchesTheBuiltInExample) {
  auto sc = io::load_problem(source_path("examples/paper/paper.yaml"));
  IntegratorOptions io_file = sc->integrator;
  io_file.t1 = 1.0;
  ReferenceDynamics rd_file(sc->model, sc->forces, sc->constraints, sc->options);
  const Plan from_file = plan_motion(rd_file, rd_file.make_state(sc->q0, sc->qd0), {io_file, sc->residual_from});

  models::PaperExample ex;
  IntegratorOptions io_ref = ex.integrator();
  io_ref.t1 = 1.0;
  ReferenceDynamics rd_ref(ex.model, ex.forces, ex.constraints, ex.options());
  const Plan builtin = plan_motion(rd_ref, rd_ref.make_state(ex.q0(), Eigen::VectorXd::Zero(3)), {io_ref});

  ASSERT_TRUE(from_file.summary.ok()) << from_file.summary.message;
  ASSERT_TRUE(builtin.summary.ok()) << builtin.summary.message;
  ASSERT_EQ(from_file.t.size(), builtin.t.size());
  ASSERT_NEAR(from_file.t.back(), 1.0, 1e-12);
  const Eigen::VectorXd q_file = from_file.x.back().head(3), q_ref = builtin.x.back().head(3);
  report("paper", "max |q_file(1 s) - q_builtin(1 s)|", (q_file - q_ref).cwiseAbs().maxCoeff());
  EXPECT_TRUE(test::near(q_file, q_ref, 0.0, 1e-10));
  EXPECT_NEAR(q_file[0], 0.30556157, 1e-7);  // ψ1(1 s) [rad]
  EXPECT_NEAR(q_file[2], 0.51502438, 1e-7);  // z3(1 s) [m]
}

// ---------------------------------------------------------------------------------------------
// 5b. Stiff friction (examples/stiff_friction): stick–slip of one joint under a torque ramp,
// integrated by BDF. Sticking: while τ = rate·t stays below the break-away level μ_s the table
// does not move (only the bristles deflect, z = τ/σ0); slipping: past μ_s it breaks away and the
// net torque τ − (≈ μ_k) accelerates it.
TEST(Examples, StickSlipTableSticksBelowTheBreakAwayTorqueThenSlips) {
  const Planned p = plan_file("examples/stiff_friction/stick_slip.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  const double mu_s = p.param("mu_s"), mu_k = p.param("mu_k"), rate = p.param("rate"), sigma0 = p.param("sigma0");
  const double J = p.param("J"), t_break = mu_s / rate;
  double stuck_speed = 0, stuck_angle = 0, worst_bristle = 0;
  for (size_t k = 0; k < p.plan.t.size(); ++k) {
    const double t = p.plan.t[k];
    if (t > 0.8 * t_break) break;
    stuck_speed = std::max(stuck_speed, std::abs(p.qd(k)[0]));
    stuck_angle = std::max(stuck_angle, std::abs(p.q(k)[0]));
    if (t > 0.1) worst_bristle = std::max(worst_bristle, std::abs(p.plan.x[k][2] * sigma0 / (rate * t) - 1));
  }
  report("stick_slip", "max |qd| while tau < 0.8 mu_s [rad/s]", stuck_speed);
  report("stick_slip", "max |q| while tau < 0.8 mu_s [rad]", stuck_angle);
  EXPECT_LT(stuck_speed, 1e-4);
  EXPECT_LT(stuck_angle, 1e-5);  // presliding: micro-radians
  EXPECT_LT(worst_bristle, 0.05);  // the bristles carry the torque: sigma0 z = tau
  // Slipping: well past the break-away the table turns and accelerates at about (τ − μ_k)/J.
  const size_t last = p.plan.t.size() - 1;
  const double t_end = p.plan.t[last];
  ASSERT_GT(t_end, 1.5 * t_break);
  EXPECT_GT(p.qd(last)[0], 0.5);
  const double accel = p.plan.qdd[last][0], expected = (rate * t_end - mu_k) / J;
  report("stick_slip", "qdd(t1) / ((tau - mu_k)/J)", accel / expected);
  EXPECT_NEAR(accel / expected, 1.0, 0.05);
  EXPECT_GT(p.plan.summary.jacobian_evaluations, 0);
}

// ---------------------------------------------------------------------------------------------
// 5c. Mixed orders (examples/mixed_orders): a holonomic height row and a jerk row (the derivative
// of an acceleration-level law) on a spatial 3R arm with LuGre friction. Checked from the
// recorded motion alone: the tip's recorded height, and the acceleration-level law with a_E from
// central differences of the recorded tip positions (error ~h²/12 |d⁴r/dt⁴|) and q̈ from the
// recorded state.
TEST(Examples, MixedOrdersKeepTheHeightAndTheWristLaw) {
  const Planned p = plan_file("examples/mixed_orders/mixed_orders.yaml");
  ASSERT_TRUE(p.plan.summary.ok()) << p.plan.summary.message;
  ASSERT_TRUE(p.sc->is_jerk_problem());
  const Model& m = p.sc->model;
  const double a = p.param("a"), z0 = p.param("z0"), h = p.sc->integrator.step;
  const int E = m.point_index("E");
  Data data(m);
  auto tip = [&](size_t k) {
    forward_kinematics(m, data, p.q(k));
    return point_position(m, data, E);
  };
  double height = 0, law = 0, law_scale = 0;
  for (size_t k = 1; k + 1 < p.plan.t.size(); ++k) {
    const double t = p.plan.t[k];
    height = std::max(height, std::abs(tip(k).z() - z0 - a * std::sin(t)));
    const Vec3 acc = (tip(k + 1) - 2 * tip(k) + tip(k - 1)) / (h * h);
    const Eigen::VectorXd& x = p.plan.x[k];
    const double q2 = x[1], qd1 = x[3], qdd3 = x[8];
    law = std::max(law, std::abs(qdd3 + 0.2 * std::cos(q2) * acc.z() + 0.1 * qd1 * acc.y() - 0.8 * std::cos(2 * t)));
    law_scale = std::max(law_scale, std::abs(0.8 * std::cos(2 * t)));
  }
  std::printf("[ mixed_orders ] max |z(E) - z0 - a sin t| = %.2e m, max |wrist law| = %.2e 1/s^2 (its terms up to %.2f)\n",
              height, law, law_scale);
  EXPECT_LT(height, 1e-6);
  EXPECT_LT(law, 1e-5);
  EXPECT_EQ(p.plan.state_names.back(), "z_q1");
}

// ---------------------------------------------------------------------------------------------
// 6. Every example through the command line: check and plan exit 0 and plan writes plan.csv.
TEST(Examples, RunThroughTheCommandLine) {
  char tmpl[] = "/tmp/refdyn_examples_XXXXXX";
  ASSERT_NE(::mkdtemp(tmpl), nullptr);
  const fs::path tmp(tmpl);
  const std::vector<std::string> files{"examples/planar_2r_circle/planar_2r_circle.yaml", "examples/unicycle/unicycle.yaml",
                                       "examples/four_bar/four_bar.yaml", "examples/urdf_arm_line/urdf_arm_line.yaml",
                                       "examples/waiter_tray/waiter_tray.yaml", "examples/paper/paper.yaml",
                                       "examples/stiff_friction/stiff_friction.yaml",
                                       "examples/stiff_friction/stick_slip.yaml",
                                       "examples/mixed_orders/mixed_orders.yaml",
                                       "examples/paper/duration.yaml", "examples/waiter_tray/fastest.yaml"};
  for (const auto& rel : files) {
    const std::string file = source_path(rel), name = fs::path(rel).stem().string();
    const fs::path out = tmp / name;
    const std::string check = std::string("'") + REFDYN_CLI + "' check '" + file + "' > '" + (tmp / (name + "_check.txt")).string() + "' 2>&1";
    const std::string plan = std::string("'") + REFDYN_CLI + "' plan '" + file + "' -q -o '" + out.string() + "' > '" +
                             (tmp / (name + "_plan.txt")).string() + "' 2>&1";
    int rc = std::system(check.c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << rel << ": refdyn check: " << read_text(tmp / (name + "_check.txt"));
    rc = std::system(plan.c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << rel << ": refdyn plan: " << read_text(tmp / (name + "_plan.txt"));
    EXPECT_TRUE(fs::is_regular_file(out / "plan.csv")) << rel;
    EXPECT_GT(fs::file_size(out / "plan.csv"), 0u) << rel;
    EXPECT_TRUE(fs::is_regular_file(out / "summary.json")) << rel;
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
}
