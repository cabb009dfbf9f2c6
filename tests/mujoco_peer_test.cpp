// refdyn's dynamics against MuJoCo's (bench/mujoco_peer.hpp): an independent implementation of
// the same quantities — MuJoCo compiles its own model from an MJCF written from refdyn's, holds
// the inertia in principal axes about the centre of mass, and runs its own CRB and RNE in the
// world frame at the subtree centres of mass. Checked on random chains and trees (revolute and
// prismatic joints, standard and modified DH, fixed links folded, general axes, armature), the
// paper's arm and the URDF arms of examples/ and tests/data/urdf/: M, c + g, g, τ (two MuJoCo
// routes) and q̈ from forward dynamics.
#include "mujoco_peer.hpp"

#include "refdyn/io/urdf.hpp"
#include "refdyn/models/paper_manipulator.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <filesystem>
#include <random>

namespace refdyn {
namespace {

using refdyn_bench::MujocoPeer;

struct Case {
  std::string label;
  Model model;
};

std::vector<Case> cases() {
  std::mt19937 rng(20261130);
  std::vector<Case> out;
  for (auto& c : test::random_model_family(rng, {1, 2, 5, 9}, test::randomize_axes, "tree, general axes +fixed"))
    out.push_back({c.label, build_model(c.desc)});
  // Armature on two of every three joints of a chain and a tree.
  for (bool tree : {false, true}) {
    test::RandomChainOptions o;
    o.dof = 7;
    o.tree = tree;
    ModelDescription d = test::random_chain(rng, o);
    for (size_t i = 0; i < d.links.size(); ++i)
      if (i % 3 != 2) d.links[i].armature = 0.05 + 0.3 * static_cast<double>(i);
    out.push_back({tree ? "tree with armature" : "chain with armature", build_model(d)});
  }
  out.push_back({"paper arm", models::paper_manipulator()});
  const std::filesystem::path src(REFDYN_SOURCE_DIR);
  // arm7_hand's mimic finger is a constraint (a joint coupling) in refdyn, which the dynamics
  // checked here do not include: both fingers are coordinates, as in MuJoCo's model. Its Drake
  // rotor tags give armature.
  std::vector<io::UrdfMimic> mimics;
  for (const auto& urdf : {src / "examples" / "urdf" / "arm7.urdf",
                           src / "tests" / "data" / "urdf" / "refdyn_test_arm" / "urdf" / "arm6.urdf",
                           src / "tests" / "data" / "urdf" / "refdyn_test_arm" / "urdf" / "arm7_hand.urdf"})
    out.push_back({urdf.filename().string(), build_model(io::load_urdf(urdf.string(), {}, &mimics))});
  return out;
}

double cond(const Eigen::MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
  return es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
}

TEST(MujocoPeer, MassMatrixBiasGravityInverseAndForwardDynamicsAgree) {
  std::mt19937 rng(7);
  int checked = 0;
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.label);
    const Model& m = c.model;
    MujocoPeer mj(m);
    ASSERT_EQ(mj.dof(), m.nq);
    // MuJoCo holds refdyn's inertias to rounding (principal axes given, not computed by MuJoCo).
    EXPECT_LE(mj.inertia_error(), 1e-14);
    Data data(m);
    for (int k = 0; k < 5; ++k) {
      const Eigen::VectorXd q = test::random_vector(rng, m.nq, 3.0), qd = test::random_vector(rng, m.nq, 2.0),
                            qdd = test::random_vector(rng, m.nq, 5.0), tau = test::random_vector(rng, m.nq, 20.0);
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(m.nq);
      const Eigen::MatrixXd M = mass_matrix(m, data, q);
      EXPECT_LE(test::rel_diff(M, mj.mass_matrix(q)), 1e-12) << "M, state " << k;
      const Eigen::VectorXd cg = bias_forces(m, data, q, qd);
      EXPECT_LE(test::rel_diff(cg, mj.bias_forces(q, qd)), 1e-12) << "c + g, state " << k;
      const Eigen::VectorXd g = gravity_forces(m, data, q);
      EXPECT_LE(test::rel_diff(g, mj.bias_forces(q, zero)), 1e-12) << "g, state " << k;
      const Eigen::VectorXd tau_id = inverse_dynamics(m, data, q, qd, qdd);
      EXPECT_LE(test::rel_diff(tau_id, mj.inverse_dynamics(q, qd, qdd)), 1e-12) << "τ (mj_rne), state " << k;
      EXPECT_LE(test::rel_diff(tau_id, mj.inverse_dynamics_pipeline(q, qd, qdd)), 1e-12)
          << "τ (mj_inverse), state " << k;
      // q̈ of two backward-stable solves differs by up to cond(M)·ε relative.
      const Eigen::VectorXd a = forward_dynamics(m, data, q, qd, tau);
      EXPECT_LE(test::rel_diff(a, mj.forward_dynamics(q, qd, tau)), 1e-13 * cond(M) + 1e-12) << "q̈, state " << k;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 16 + 2 + 1 + 3);
}

TEST(MujocoPeer, TimedKernelsComputeTheSameQuantities) {
  // The timed calls (stored states, MuJoCo's order) run the same pipelines as the checked ones:
  // after time_* the checked call at the same state gives the same numbers bit for bit.
  std::mt19937 rng(11);
  test::RandomChainOptions o;
  o.dof = 6;
  o.tree = true;
  const Model m = build_model(test::random_chain(rng, o));
  MujocoPeer mj(m);
  std::vector<Eigen::VectorXd> q, qd, qdd, tau;
  for (int k = 0; k < 3; ++k) {
    q.push_back(test::random_vector(rng, m.nq, 3.0));
    qd.push_back(test::random_vector(rng, m.nq, 2.0));
    qdd.push_back(test::random_vector(rng, m.nq, 5.0));
    tau.push_back(test::random_vector(rng, m.nq, 20.0));
  }
  mj.load_states(q, qd, qdd, tau);
  for (int k = 0; k < 3; ++k) {
    mj.time_forward_dynamics(k);
    const Eigen::VectorXd timed = mj.last_qdd();
    EXPECT_EQ(timed, mj.forward_dynamics(q[k], qd[k], tau[k])) << "state " << k;
    mj.time_bias_forces(k);
    const Eigen::VectorXd timed_cg = mj.last_bias_forces();
    EXPECT_EQ(timed_cg, mj.bias_forces(q[k], qd[k])) << "state " << k;
    mj.time_inverse_dynamics(k);
    const Eigen::VectorXd timed_tau = mj.last_tau();
    EXPECT_EQ(timed_tau, mj.inverse_dynamics(q[k], qd[k], qdd[k])) << "state " << k;
    mj.time_mass_matrix(k);
    const Eigen::MatrixXd timed_M = mj.last_mass_matrix();
    EXPECT_EQ(timed_M, mj.mass_matrix(q[k])) << "state " << k;
  }
}

TEST(MujocoPeer, ModelWithoutMassIsRejectedWithMujocosMessage) {
  std::mt19937 rng(3);
  test::RandomChainOptions o;
  o.dof = 3;
  ModelDescription d = test::random_chain(rng, o);
  d.links.front().inertia = LinkInertia{};  // M stays positive definite: its children carry mass
  const Model m = build_model(d);
  try {
    MujocoPeer mj(m);
    ADD_FAILURE() << "MuJoCo accepted a moving body without mass";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("MuJoCo rejected the model"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("inertia"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("b0"), std::string::npos) << e.what();  // the body
  }
}

TEST(MujocoPeer, MjcfNestsBodiesAsTheTreeAndCarriesEveryParameter) {
  std::mt19937 rng(5);
  test::RandomChainOptions o;
  o.dof = 4;
  o.tree = true;
  ModelDescription d = test::random_chain(rng, o);
  d.links[1].armature = 0.25;
  const Model m = build_model(d);
  const std::string xml = MujocoPeer::mjcf(m);
  for (int i = 0; i < m.nq; ++i) {
    EXPECT_NE(xml.find("<body name=\"b" + std::to_string(i) + "\""), std::string::npos);
    EXPECT_NE(xml.find("<joint name=\"j" + std::to_string(i) + "\""), std::string::npos);
  }
  EXPECT_NE(xml.find("armature=\"0.25\""), std::string::npos);
  EXPECT_NE(xml.find("<flag contact=\"disable\" constraint=\"disable\"/>"), std::string::npos);
  // Each body closes after its children: the depth of b_i's opening line is that of its parent + 1.
  for (int i = 0; i < m.nq; ++i) {
    auto indent_of = [&](int b) {
      const size_t at = xml.find("<body name=\"b" + std::to_string(b) + "\"");
      return at - xml.rfind('\n', at) - 1;
    };
    if (m.parent[i] >= 0) {
      EXPECT_EQ(indent_of(i), indent_of(m.parent[i]) + 2) << "body " << i;
    } else {
      EXPECT_EQ(indent_of(i), 4u) << "body " << i;
    }
  }
}

}  // namespace
}  // namespace refdyn
