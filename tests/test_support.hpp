#pragma once
// Shared helpers for the test suite: seeded random models and states, and one tolerance check.
#include "refdyn/common/error.hpp"
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/model.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace refdyn::test {

/// |a − b| <= abs_tol + rel_tol · max(|a|, |b|) entrywise (max norm); prints the worst entry.
::testing::AssertionResult near(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double rel_tol,
                                double abs_tol = 0.0);

/// Largest relative difference ‖a − b‖∞ / max(‖a‖∞, ‖b‖∞, floor).
double rel_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double floor = 1e-300);

struct RandomChainOptions {
  int dof = 6;
  double prismatic_fraction = 0.3;
  bool modified_dh = false;
  bool with_fixed_joints = false;   ///< insert some fixed links (folded by build_model)
  bool tree = false;                ///< random parents instead of a serial chain
  bool random_base = true;
};

/// A random physically valid model: random DH parameters, masses, COM offsets and inertias
/// (SPD, triangle inequality), with a point "tip" on the last link.
ModelDescription random_chain(std::mt19937& rng, const RandomChainOptions& opt = {});

Eigen::VectorXd random_vector(std::mt19937& rng, int n, double scale = 1.0);

/// One random model of a family: its label ("standard chain n=5", …) and description.
struct RandomModelCase {
  std::string label;
  ModelDescription desc;
};
/// For each size, four random models in this order: a standard-DH chain, a modified-DH chain
/// with fixed links, a tree, and a tree with fixed links whose joint axes `general_axes` rewrites
/// (labelled with `general_label`). The draws from rng follow that order.
std::vector<RandomModelCase> random_model_family(std::mt19937& rng, const std::vector<int>& sizes,
                                                 const std::function<void(std::mt19937&, ModelDescription&)>& general_axes,
                                                 const std::string& general_label);

/// The whole file as bytes ("" if it cannot be read).
std::string read_file(const std::string& path);

/// Expects fn() to throw refdyn::Error whose message contains every needle.
template <typename Fn>
void expect_error_mentioning(Fn&& fn, const std::vector<std::string>& needles) {
  try {
    fn();
  } catch (const Error& e) {
    const std::string what = e.what();
    for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
    return;
  }
  ADD_FAILURE() << "expected refdyn::Error mentioning '" << (needles.empty() ? std::string() : needles.front()) << "'";
}

}  // namespace refdyn::test

namespace refdyn::test {

/// Reference forward kinematics computed straight from a ModelDescription, independent of
/// build_model's folding: T^(l) = T^(parent) · P_l · J_l(q_l) · L_l for every description link
/// (fixed links included), with J_l from Eigen::AngleAxis / a translation along the axis.
/// q is indexed by the movable links in description order (the Model's coordinate order).
std::vector<SE3> reference_link_poses(const ModelDescription& d, const Eigen::VectorXd& q);

/// Position in {0} of the named point of `d`, by reference_link_poses.
Vec3 reference_point_position(const ModelDescription& d, const Eigen::VectorXd& q,
                              const std::string& point);

/// Description index of the link behind each Model body (the movable links, in order).
std::vector<int> movable_links(const ModelDescription& d);


/// The kinematics and constraint tests' random models (one zoo, drawn in this order from rng):
/// revolute + prismatic joints, standard + modified DH, chains + trees, and with `variants` = 8
/// also with fixed links; random_chain's tip plus "mid" on a middle link and "anchor" in the
/// world. Labels: "standard chain", "modified tree +fixed", …, with " n=<dof>" when asked.
struct ZooOptions {
  double prismatic_fraction = 0.35;
  Vec3 mid{0.15, -0.25, 0.2};
  Vec3 anchor{0.4, -0.3, 0.8};
  int variants = 8;            ///< 4: no fixed links
  bool dof_in_label = false;
};
std::vector<RandomModelCase> model_zoo(std::mt19937& rng, int dof, const ZooOptions& o = {});

/// A constraint from a factory, named.
ConstraintPtr renamed(NewConstraint c, const std::string& name);
/// Replaces every joint axis by a random unit vector, except that some are set exactly to
/// −z, +x or −y (the recursive kernels have special cases for ±z and a general path).
void randomize_axes(std::mt19937& rng, ModelDescription& d);
/// A random unit vector (never from a nearly zero draw).
Vec3 random_unit(std::mt19937& rng);
/// Every ready-made kind of constraints.hpp on a model with points "tip", "mid" and "anchor"
/// (the constraint tests' zoo: random_chain's tip plus those two).
ConstraintSet all_kinds(const Model& model, std::mt19937& rng);

}  // namespace refdyn::test
