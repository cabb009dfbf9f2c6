// The test robots of tests/data/urdf (URDFs written for the tests in the shape of real robot
// descriptions: the description package refdyn_test_arm with a 7-joint arm + gripper and a 6-joint
// arm) through the pipeline: check (the armature read from Drake's rotor tags and its note, the
// URDF's <dynamics> as force elements or ignored with a note, model.armature), plan (the task
// held, the mimic finger coupled; on a prescribed motion the armature's share of the effort is
// exactly a_i q̈_i), track and the command line (ROS_PACKAGE_PATH for the meshes). The report with the meshes: tests/report_browser_test.py;
// the generated C with armature: tests/symbolic_c_test.cpp (tests/data/symbolic/armature.yaml).
#include "refdyn/io/check.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/plan.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace refdyn {
namespace {

namespace fs = std::filesystem;

std::string data_path(const std::string& rel) { return std::string(REFDYN_SOURCE_DIR) + "/tests/data/urdf/" + rel; }

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// The arm7_hand scenario with `from` replaced by `to` (read from its folder, so relative paths hold).
std::unique_ptr<Problem> arm7_variant(const std::string& from, const std::string& to) {
  std::string text = test::read_file(data_path("arm7_hand.yaml"));
  const size_t at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("arm7_hand.yaml has no '" + from + "'");
  text.replace(at, from.size(), to);
  return io::parse_problem(text, data_path("arm7_hand_variant.yaml"));
}

TEST(UrdfScenario, CheckSaysWhereTheArmatureAndTheForcesComeFrom) {
  const ScenarioSpec spec = io::parse_scenario(test::read_file(data_path("arm7_hand.yaml")), data_path("arm7_hand.yaml"));
  const io::CheckReport r = io::check_scenario(spec, "arm7_hand.yaml");
  const std::string text = io::check_text(r);
  EXPECT_TRUE(contains(text, "joint1  revolute  link 'link1'  parent base  mass 4 kg  armature 3.35 kg m^2")) << text;
  EXPECT_TRUE(contains(text, "note: armature [kg m^2] from the URDF's <drake:rotor_inertia> x <drake:gear_ratio>^2: joint1 "
                             "3.35 (0.000335 x 100^2)")) << text;
  EXPECT_TRUE(contains(text, "joint7 1.16 (0.000116 x 100^2)")) << text;
  EXPECT_TRUE(contains(text, "note: the URDF's <dynamics> are force elements (model.urdf.dynamics): damping on joint1, ")) << text;
  EXPECT_TRUE(contains(text, "LuGre friction (mu_s = mu_k = F, sigma0 = 100 F per rad) on joint1, ")) << text;
  // 7 damping + 7 LuGre elements from the URDF, ahead of the file's 4 springs
  ASSERT_EQ(r.force_elements.size(), 18u);
  EXPECT_EQ(r.force_elements.front(), "damping(joint1)");
  EXPECT_EQ(r.force_elements[1], "lugre(joint1)");
  EXPECT_EQ(r.force_elements.back(), "spring(joint7)");
  EXPECT_EQ(r.constraints.front().name, "mimic_finger_joint2");
  EXPECT_EQ(r.model_notes.size(), 2u);
}

TEST(UrdfScenario, DynamicsAreIgnoredUnlessAskedForAndSaySo) {
  const auto p = arm7_variant("    dynamics: true\n", "");
  EXPECT_EQ(p->forces.elements().size(), 4u);  // the springs only
  ASSERT_EQ(p->model_notes.size(), 2u);
  EXPECT_TRUE(contains(p->model_notes[1], "the URDF's <dynamics> (damping, friction) of joints joint1, joint2")) << p->model_notes[1];
  EXPECT_TRUE(contains(p->model_notes[1], "are ignored (model.urdf.dynamics: true adds them")) << p->model_notes[1];
}

TEST(UrdfScenario, ModelArmatureReplacesTheDrakeValue) {
  const auto p = arm7_variant("    dynamics: true\n", "    dynamics: true\n  armature: {joint1: 0.5, finger_joint1: 0.01}\n");
  const Model& m = p->model;
  EXPECT_EQ(m.armature[m.joint_index("joint1")], 0.5);
  EXPECT_EQ(m.armature[m.joint_index("joint2")], 3.35);
  EXPECT_EQ(m.armature[m.joint_index("finger_joint1")], 0.01);
  bool noted = false;
  for (const std::string& n : p->model_notes) noted = noted || contains(n, "joint joint1: armature 0.5 from model.armature (replaces the URDF's 3.35)");
  EXPECT_TRUE(noted);
  test::expect_error_mentioning([] { arm7_variant("    dynamics: true\n", "    dynamics: true\n  armature: {flange_joint: 1}\n"); },
                                {"model.armature.flange_joint", "unknown joint 'flange_joint'"});
}

/// Plans a problem as `refdyn plan` does (io::run_problem without experiments).
io::Results plan_of(const Problem& p) {
  io::RunOptions o;
  o.track = false;
  return io::run_problem(p, o);
}

TEST(UrdfScenario, PlanHoldsTheTaskAndTheMimic) {
  const auto p = io::load_problem(data_path("arm7_hand.yaml"));
  const io::Results r = plan_of(*p);
  ASSERT_TRUE(r.plan.summary.ok()) << r.plan.summary.message;
  EXPECT_LT(r.plan.summary.max_constraint_residual, 1e-9);
  EXPECT_TRUE(r.feasibility.feasible());
  const Model& m = p->model;
  const int f1 = m.joint_index("finger_joint1"), f2 = m.joint_index("finger_joint2");
  for (const Eigen::VectorXd& x : r.plan.x) EXPECT_NEAR(x[f2], x[f1], 1e-10);  // the mimic coupling
  EXPECT_NEAR(r.plan.x.back()[f1], 0.035, 1e-9);                              // opened by 0.03 m
  EXPECT_EQ(p->forces.num_states(), 7);  // a bristle state per LuGre element
}

/// Every joint of the arm prescribed (q_j = h_j + 0.3 sin(2πt/T + j)), the gripper opening: the
/// motion does not depend on M, so with and without the rotors q, q̇, q̈ agree and the
/// constraint forces Q_c = M q̈ − F differ by exactly the armature's share a_i q̈_i.
std::string prescribed(const std::string& armature) {
  std::string y = "name: arm7_prescribed\nparameters: {T: 1}\nmodel:\n  urdf:\n"
                  "    file: refdyn_test_arm/urdf/arm7_hand.urdf\n    dynamics: true\n" + armature + "constraints:\n";
  const double h[7] = {0.2, 0.5, 0, -1.2, 0, 0.9, 0};
  for (int j = 0; j < 7; ++j)
    y += "  - {name: p" + std::to_string(j + 1) + ", kind: joint_trajectory, joint: joint" + std::to_string(j + 1) +
         ", function: " + std::to_string(h[j]) + " + 0.3*sin(2*pi*t/T + " + std::to_string(j) + ")}\n";
  y += "  - {name: open, kind: joint_trajectory, joint: finger_joint1, function: {cycloidal: {rise: 0.03, duration: T, "
       "from: 0.005}}}\ninitial:\n  q: {";
  for (int j = 0; j < 7; ++j) y += "joint" + std::to_string(j + 1) + ": " + std::to_string(h[j] + 0.3 * std::sin(j)) + ", ";
  y += "finger_joint1: 0.005, finger_joint2: 0.005}\n  consistency: project\nintegrator: {method: rk4, step: 1e-3, t0: 0, t1: 1}\n";
  return y;
}

TEST(UrdfScenario, TheArmaturesShareOfThePrescribedMotionsEffortIsItsInertiaTimesTheAcceleration) {
  const auto with = io::parse_problem(prescribed(""), data_path("arm7_prescribed.yaml"));
  const auto bare = io::parse_problem(prescribed("  armature: {joint1: 0, joint2: 0, joint3: 0, joint4: 0, joint5: 0, joint6: 0, "
                                                 "joint7: 0}\n"), data_path("arm7_prescribed.yaml"));
  const io::Results rw = plan_of(*with), rb = plan_of(*bare);
  ASSERT_TRUE(rw.plan.summary.ok()) << rw.plan.summary.message;
  ASSERT_TRUE(rb.plan.summary.ok()) << rb.plan.summary.message;
  ASSERT_EQ(rw.plan.size(), rb.plan.size());
  const Model& m = with->model;
  const Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(m.armature.data(), m.nq);
  double worst_motion = 0, worst_share = 0, largest_share = 0;
  for (size_t k = 0; k < rw.plan.size(); ++k) {
    worst_motion = std::max({worst_motion, test::rel_diff(rw.plan.x[k], rb.plan.x[k], 1.0),
                             test::rel_diff(rw.plan.qdd[k], rb.plan.qdd[k], 1.0)});
    const Eigen::VectorXd share = a.cwiseProduct(rw.plan.qdd[k]);
    worst_share = std::max(worst_share, test::rel_diff(rw.plan.Qc[k] - rb.plan.Qc[k], share, 1.0));
    largest_share = std::max(largest_share, share.cwiseAbs().maxCoeff());
  }
  std::printf("arm7 prescribed: motions agree to %.1e, Q_c(with) - Q_c(without) = a qdd to %.1e (largest a_i qdd_i %.3g N m)\n",
              worst_motion, worst_share, largest_share);
  EXPECT_LT(worst_motion, 1e-9);
  EXPECT_LT(worst_share, 1e-9);
  EXPECT_GT(largest_share, 5.0);  // the rotors' share is not small: 3.35 kg m^2 × up to ~12 rad/s^2
}

TEST(UrdfScenario, TrackTheSixJointArmFromTheCommandLine) {
  const fs::path out = fs::temp_directory_path() / ("refdyn_urdf_scenario_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string cmd = "ROS_PACKAGE_PATH='" + data_path("") + "' '" + std::string(REFDYN_CLI) + "' track '" +
                          data_path("arm6.yaml") + "' -o '" + out.string() + "' -q > '" + out.string() + ".log' 2>&1";
  const int rc = std::system(cmd.c_str());
  EXPECT_EQ(rc, 0) << test::read_file(out.string() + ".log");
  const std::string summary = test::read_file((out / "summary.json").string());
  EXPECT_TRUE(contains(summary, "\"status\": \"success\"")) << summary.substr(0, 400);
  EXPECT_TRUE(fs::exists(out / "track_offset.csv"));
  const std::string plan = test::read_file((out / "plan.csv").string());
  EXPECT_FALSE(contains(plan.substr(0, plan.find('\n')), "z_"));  // damping only: no LuGre state
  fs::remove_all(out);
  fs::remove(out.string() + ".log");
}

}  // namespace
}  // namespace refdyn
