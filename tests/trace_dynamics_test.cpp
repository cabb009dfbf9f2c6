// The paper's trace route against the recursive spatial-vector route.
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/multibody/trace_dynamics.hpp"
#include "test_support.hpp"

using namespace refdyn;
using refdyn::test::near;

TEST(TraceDynamics, MatchesRecursiveOnRandomChains) {
  std::mt19937 rng(12345);
  for (int n : {1, 2, 3, 5, 8, 13, 21, 30}) {
    for (int rep = 0; rep < 3; ++rep) {
      test::RandomChainOptions o;
      o.dof = n;
      o.modified_dh = rep == 1;
      const Model model = build_model(test::random_chain(rng, o));
      Data data(model);
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0);
      EXPECT_TRUE(near(trace_mass_matrix(model, data, q), mass_matrix(model, data, q), 1e-10)) << "n=" << n;
      const Eigen::VectorXd g = gravity_forces(model, data, q);
      EXPECT_TRUE(near(trace_gravity(model, data, q), g, 1e-10)) << "n=" << n;
      // c alone is exactly zero for n = 1; compare c + g, whose scale is set by gravity.
      const Eigen::VectorXd cg = trace_coriolis(model, data, q, qd) + trace_gravity(model, data, q);
      EXPECT_TRUE(near(cg, bias_forces(model, data, q, qd), 1e-10)) << "n=" << n;
    }
  }
}
