#pragma once
// Shared helpers for the test suite: seeded random models and states, and one tolerance check.
#include "refdyn/model.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>
#include <string>

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

}  // namespace refdyn::test
