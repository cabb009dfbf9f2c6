// Reference dynamics (GPME): the projection solver against the Lagrange (KKT) solver on random
// chains with random constraint mixes; Baumgarte error dynamics against their closed-form
// solutions; closed-form rheonomic (bead on a spinning wire) and nonholonomic (knife edge)
// motions; singular partitions; paper-literal forces; make_consistent.
#include "refdyn/common/error.hpp"
#include "refdyn/simulate/integrators.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/models/paper_example.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <numeric>
#include <tuple>

using namespace refdyn;
using refdyn::test::expect_error_mentioning;
using refdyn::test::near;

namespace {

// ---------------------------------------------------------------- helpers

IntegrationSummary run(ReferenceDynamics& rd, Eigen::VectorXd& x, const IntegratorOptions& o,
                       const OdeObserver& obs = {}) {
  return integrate([&](double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) { rd.derivative(t, xx, dx); }, x,
                   o, obs);
}

IntegratorOptions rk4(double t1, double h, double t0 = 0.0) {
  IntegratorOptions o;
  o.method = IntegratorMethod::RK4;
  o.t0 = t0;
  o.t1 = t1;
  o.step = h;
  return o;
}

ConstraintPtr renamed(NewConstraint c, const std::string& name) {
  c->name = name;
  return c;
}

/// Planar n-R arm in the horizontal x–y plane (joint axes vertical: gravity does no work), links
/// of length L and mass m with the centre of mass mid-link; joints "q1".."qn"; point "tip" at
/// the end of the last link.
ModelDescription planar_arm(int n, double L = 1.0, double m = 1.0) {
  ModelDescription d;
  d.name = "planar_arm";
  for (int i = 0; i < n; ++i) {
    LinkSpec l;
    l.name = "link" + std::to_string(i + 1);
    l.joint_name = "q" + std::to_string(i + 1);
    l.parent = i - 1;
    l.placement = i == 0 ? SE3::Identity() : SE3::trans(Vec3(L, 0, 0));
    l.inertia.mass = m;
    l.inertia.com = Vec3(L / 2, 0, 0);
    l.inertia.I_com = Vec3(1e-3, m * L * L / 12, m * L * L / 12).asDiagonal();
    d.add_link(l);
  }
  d.add_point("tip", d.links.back().name, Vec3(L, 0, 0));
  return d;
}

/// Bead (point mass mb at the origin of the "bead" body) on a straight wire through the
/// vertical axis; the wire spins about z (joint "spin"), the bead slides along it ("bead").
ModelDescription bead_on_wire(double mb) {
  ModelDescription d;
  d.name = "bead_on_wire";
  LinkSpec wire;
  wire.name = "wire";
  wire.joint_name = "spin";
  wire.inertia.mass = 1.5;
  wire.inertia.I_com = Vec3(0.1, 0.1, 0.15).asDiagonal();
  d.add_link(wire);
  LinkSpec bead;
  bead.name = "bead";
  bead.joint_name = "bead";
  bead.parent = 0;
  bead.type = JointType::Prismatic;
  bead.axis = Vec3::UnitX();
  bead.inertia.mass = mb;  // point mass: no rotational inertia
  d.add_link(bead);
  d.add_point("B", "bead", Vec3::Zero());
  return d;
}

/// Knife edge / sleigh: carriages along x and y (massless), a body rotating about z carrying
/// the blade at its centre of mass.
ModelDescription sleigh(double m, double J) {
  ModelDescription d;
  d.name = "sleigh";
  LinkSpec cx;
  cx.name = "cx";
  cx.joint_name = "x";
  cx.type = JointType::Prismatic;
  cx.axis = Vec3::UnitX();
  d.add_link(cx);
  LinkSpec cy;
  cy.name = "cy";
  cy.joint_name = "y";
  cy.parent = 0;
  cy.type = JointType::Prismatic;
  cy.axis = Vec3::UnitY();
  d.add_link(cy);
  LinkSpec body;
  body.name = "body";
  body.joint_name = "theta";
  body.parent = 1;
  body.inertia.mass = m;
  body.inertia.I_com = Vec3(J, J, J).asDiagonal();  // Izz = J (triangle inequality holds)
  d.add_link(body);
  d.add_point("P", "body", Vec3::Zero());
  return d;
}

/// A force F along the sleigh's heading (cos θ, sin θ) on the x, y carriages.
class ForwardForce final : public ForceElement {
 public:
  explicit ForwardForce(double F) : F_(F) {}
  std::string name() const override { return "forward_force"; }
  void apply(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, const double*, Eigen::VectorXd& Q, double*,
             Eigen::MatrixXd*) const override {
    Q[0] += F_ * std::cos(q[2]);
    Q[1] += F_ * std::sin(q[2]);
  }
 private:
  double F_;
};

/// Signed constraint values Φ (or c) at (t, x), evaluated independently of the solver.
struct Residuals {
  Residuals(const Model& model, const ConstraintSet& set) : model(model), set(set), data(model), ev(model, set) {}
  const Eigen::VectorXd& operator()(double t, const Eigen::VectorXd& x) {
    const int n = model.nq;
    evaluate_constraints(model, data, set, ev, t, x.head(n), x.segment(n, n));
    return ev.phi;
  }
  const Model& model;
  const ConstraintSet& set;
  Data data;
  ConstraintEval ev;
};

// ---------------------------------------------------------------- random constraint mixes

Vec3 random_unit(std::mt19937& rng) {
  Vec3 v = test::random_vector(rng, 3);
  while (v.norm() < 0.1) v = test::random_vector(rng, 3);
  return v.normalized();
}

/// Random constraints until `rows` rows (at most): surfaces, coordinates, joint trajectories,
/// loop closures, knife edges, point speeds on the points "tip" and "mid".
void add_random_constraints(const Model& model, ConstraintSet& set, int rows, std::mt19937& rng,
                            std::vector<int>& kinds) {
  std::uniform_int_distribution<int> kind(0, 7), coin(0, 1);
  std::vector<int> used_joints;
  int k = 0;
  while (set.rows() < rows) {
    const std::string pt = coin(rng) ? "tip" : "mid";
    const std::string name = "c" + std::to_string(k++);
    const int left = rows - set.rows();
    const int size_before = set.size();
    const int kd = kind(rng);
    switch (kd) {
      case 0:
        set.add(renamed(point_on_surface(model, pt, elliptic_cylinder(0.8, 0.5, 0.1, 0.2)), name));
        break;
      case 1:
        set.add(renamed(point_on_surface(model, pt, sphere(test::random_vector(rng, 3), 1.1)), name));
        break;
      case 2:
        set.add(renamed(point_on_surface(model, pt, plane(random_unit(rng), sinusoid(0.2, 1.5, 0.3, 0.1))), name));
        break;
      case 3:
        set.add(renamed(point_coordinate(model, pt, std::uniform_int_distribution<int>(0, 2)(rng),
                                         raised_cosine(0.3, 0.1, 4.0)),
                        name));
        break;
      case 4: {
        const int j = std::uniform_int_distribution<int>(0, model.nq - 1)(rng);
        if (std::find(used_joints.begin(), used_joints.end(), j) != used_joints.end()) break;
        used_joints.push_back(j);
        set.add(renamed(joint_trajectory(model, model.joint_name[j], sinusoid(0.5, 1.0, 0.2, 0.3)), name));
        break;
      }
      case 5: {
        std::vector<int> axes{0, 1, 2};
        std::shuffle(axes.begin(), axes.end(), rng);
        axes.resize(std::uniform_int_distribution<int>(1, std::min(3, left))(rng));
        set.add(renamed(points_coincide(model, "tip", "mid", axes), name));
        break;
      }
      case 6:
        set.add(renamed(knife_edge(model, pt, random_unit(rng)), name));
        break;
      case 7:
        set.add(renamed(point_speed(model, pt, random_unit(rng), sinusoid(0.3, 2.0)), name));
        break;
    }
    if (set.size() > size_before) kinds.push_back(kd);
  }
}

}  // namespace

// ================================================================ (a) projection vs Lagrange

TEST(ReferenceDynamics, ProjectionAndLagrangeAgreeOnRandomChainsAndConstraintMixes) {
  std::mt19937 rng(41);
  int compared = 0, skipped = 0;
  std::vector<int> kind_count(8, 0);  // compared sets containing each kind
  double worst_qdd = 0, worst_lambda = 0, worst_balance = 0, worst_rows = 0, worst_cond = 0;
  // From 2 DOF: every (n, m) the projection kernels specialise (n ≤ 4) and the orthonormal solve
  // at each column length it is compiled for (8, 12, 16, and 24 at run time: 17 DOF), with both of
  // its ways of forming ZᵀMZ (the random row counts fall on either side of explicit_null_basis).
  for (int dof = 2; dof <= 17; ++dof) {
    int accepted = 0;
    for (int rep = 0; rep < 40 && accepted < 5; ++rep) {
      test::RandomChainOptions opt;
      opt.dof = dof;
      opt.tree = rep % 3 == 2;
      opt.modified_dh = rep % 2;
      opt.with_fixed_joints = rep % 4 == 3;
      ModelDescription d = test::random_chain(rng, opt);
      d.add_point("mid", d.links[d.links.size() / 2].name, Vec3(0.1, -0.2, 0.15));
      const Model model = build_model(d);
      const int n = model.nq;
      ConstraintSet set;
      std::vector<int> kinds;
      add_random_constraints(model, set, std::uniform_int_distribution<int>(1, n - 1)(rng), rng, kinds);
      ASSERT_LT(set.rows(), n);
      ForceSet forces;
      forces.add(joint_damping(model, model.joint_name[0], 0.7));
      forces.add(joint_spring(model, model.joint_name[n - 1], 3.0, 0.2));
      forces.add(std::make_shared<LuGreFriction>(model, model.joint_name[n / 2], LuGreParams{}));
      forces.add(joint_effort(model, model.joint_name[1], sinusoid(1.0, 2.0)));
      ReferenceDynamicsOptions po, lo;
      po.solver = ReferenceSolver::Projection;
      lo.solver = ReferenceSolver::Lagrange;
      ReferenceDynamics proj(model, forces, set, po), lag(model, forces, set, lo);
      const Eigen::VectorXd q = test::random_vector(rng, n, 2.0), qd = test::random_vector(rng, n, 1.0);
      const double t = std::uniform_real_distribution<double>(0.0, 2.0)(rng);
      {  // Random sets can be redundant (e.g. a coordinate the point cannot move along): skip
         // those (rank-deficient A is covered by Partition.RankDeficientConstraints…).
        Data data(model);
        ConstraintEval ev(model, set);
        evaluate_constraints(model, data, set, ev, t, q, qd);
        Eigen::JacobiSVD<Eigen::MatrixXd> svd(ev.A);
        const auto& sv = svd.singularValues();
        if (!(sv(sv.size() - 1) > 1e-6 * sv(0))) {
          ++skipped;
          continue;
        }
      }
      const double cond = proj.choose_partition(t, q, qd);
      if (!(cond < 1e3)) {  // keep to states where the partition (and the KKT system) is sound
        ++skipped;
        continue;
      }
      worst_cond = std::max(worst_cond, cond);
      Eigen::VectorXd x = proj.make_state(q, qd);
      x.tail(forces.num_states()) = test::random_vector(rng, forces.num_states(), 0.01);
      Eigen::VectorXd xp(x.size()), xl(x.size());
      proj.derivative(t, x, xp);
      lag.derivative(t, x, xl);
      const std::string where = "dof " + std::to_string(n) + " rows " + std::to_string(set.rows()) + " rep " +
                                std::to_string(rep) + " cond " + std::to_string(cond);
      EXPECT_TRUE(near(proj.qdd(), lag.qdd(), 1e-10)) << where;
      EXPECT_TRUE(near(xp, xl, 1e-10)) << where;
      EXPECT_TRUE(near(xp.head(n), qd, 0, 0));
      worst_qdd = std::max(worst_qdd, test::rel_diff(proj.qdd(), lag.qdd()));
      worst_lambda = std::max(worst_lambda, test::rel_diff(proj.lambda(), lag.lambda()));
      EXPECT_TRUE(near(proj.lambda(), lag.lambda(), 1e-8)) << where;
      for (ReferenceDynamics* rd : {&proj, &lag}) {
        const Eigen::MatrixXd& A = rd->constraints().A;
        const Eigen::VectorXd minus_At_lambda = -A.transpose() * rd->lambda();
        EXPECT_TRUE(near(rd->constraint_force(), minus_At_lambda, 1e-9)) << where;
        // M q̈ − F = −Aᵀλ with F = Q − (c + g); M and c + g recomputed independently.
        Data data(model);
        mass_matrix(model, data, q);
        bias_forces(model, data, q, qd);
        // (the Lagrange solver from kAbaLagrangeFrom coordinates factors M by ABA: no mass())
        if (rd == &proj || n < kAbaLagrangeFrom) {
          EXPECT_TRUE(near(rd->mass(), data.M, 1e-13, 1e-13));
        }
        EXPECT_TRUE(near(rd->bias(), data.nle, 1e-12, 1e-12));
        const Eigen::VectorXd balance = data.M * rd->qdd() - (rd->applied_force() - data.nle);
        EXPECT_TRUE(near(balance, minus_At_lambda, 1e-9)) << where;
        worst_balance = std::max(worst_balance, test::rel_diff(balance, minus_At_lambda));
        // Stabilized constraint rows: A q̈ = −γ − 2αΦ̇ − β²Φ (holonomic), −γ − β₁c (first order).
        const ConstraintEval& ev = rd->constraints();
        Eigen::VectorXd rhs(set.rows());
        for (int r = 0; r < set.rows(); ++r)
          rhs[r] = set.row_first_order(r) ? -ev.gamma[r] - 50.0 * ev.phi[r]
                                          : -ev.gamma[r] - 200.0 * ev.phid[r] - 2500.0 * ev.phi[r];
        EXPECT_TRUE(near(A * rd->qdd(), rhs, 1e-10)) << where;
        worst_rows = std::max(worst_rows, test::rel_diff(A * rd->qdd(), rhs));
      }
      ++compared;
      ++accepted;
      for (int kd : kinds) ++kind_count[kd];
    }
    EXPECT_EQ(accepted, 5) << "dof " << dof << ": too few random sets with a well-conditioned partition";
  }
  std::cout << "[ projection vs Lagrange ] " << compared << " states (" << skipped
            << " skipped: rank-deficient A or cond(K_dc) >= 1e3); worst relative difference: qdd " << worst_qdd << ", lambda "
            << worst_lambda << "; |Mq̈ − F + Aᵀλ| rel " << worst_balance << "; constraint rows rel " << worst_rows
            << "; worst accepted cond " << worst_cond << "; constraints per kind (ellipse, sphere, plane, "
            << "coordinate, joint, coincide, knife, speed):";
  for (int c : kind_count) std::cout << " " << c;
  std::cout << "\n";
  // Every kind took part in the comparison, several times.
  for (int kd = 0; kd < 8; ++kd) EXPECT_GE(kind_count[kd], 5) << "kind " << kd;
}

// ReferenceSolver::Automatic: resolved by size at construction, and then bit for bit the
// explicit solver it names; projection and Lagrange agree on either side of the crossover.
TEST(ReferenceDynamics, AutomaticSolverPicksBySizeAndIsExactlyTheChosenSolver) {
  EXPECT_EQ(automatic_reference_solver(3, 2), ReferenceSolver::Projection);  // the paper's example
  EXPECT_EQ(automatic_reference_solver(kLagrangeFrom - 1, 4), ReferenceSolver::Projection);
  EXPECT_EQ(automatic_reference_solver(kLagrangeFrom, 4), ReferenceSolver::Lagrange);
  EXPECT_EQ(automatic_reference_solver(60, 4), ReferenceSolver::Lagrange);
  std::mt19937 rng(131);
  for (int n : {4, kLagrangeFrom - 1, kLagrangeFrom, 30, 60}) {
    test::RandomChainOptions opt;
    opt.dof = n;
    const Model model = build_model(test::random_chain(rng, opt));
    ConstraintSet set;
    set.add(point_coordinate(model, "tip", 2, constant(0.3)));
    set.add(joint_coupling(model, model.joint_name[1], model.joint_name[0], 0.5));
    ForceSet forces;
    forces.add(joint_damping(model, model.joint_name[0], 0.7));
    ReferenceDynamicsOptions o;
    o.automatic_partition = true;
    o.solver = ReferenceSolver::Automatic;
    ReferenceDynamics automatic(model, forces, set, o);
    const ReferenceSolver chosen = automatic_reference_solver(n, set.rows());
    EXPECT_EQ(automatic.options().solver, chosen) << n;
    o.solver = chosen;
    ReferenceDynamics explicit_rd(model, forces, set, o);
    o.solver = chosen == ReferenceSolver::Lagrange ? ReferenceSolver::Projection : ReferenceSolver::Lagrange;
    ReferenceDynamics other(model, forces, set, o);
    Data data(model);
    for (int rep = 0; rep < 3; ++rep) {
      const Eigen::VectorXd q = test::random_vector(rng, n, 2.0), qd = test::random_vector(rng, n, 1.0);
      const Eigen::VectorXd x = automatic.make_state(q, qd);
      Eigen::VectorXd xa(x.size()), xe(x.size()), xo(x.size());
      automatic.derivative(0.4, x, xa);
      explicit_rd.derivative(0.4, x, xe);
      EXPECT_EQ(xa, xe) << n;  // bit for bit
      EXPECT_EQ(automatic.lambda(), explicit_rd.lambda()) << n;
      other.derivative(0.4, x, xo);
      // Both solvers are backward stable: their q̈ differ by cond(M)·ε relative (as ABA and
      // CRBA + Cholesky do), where the partition is sound.
      ReferenceDynamics& proj = chosen == ReferenceSolver::Projection ? automatic : other;
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(mass_matrix(model, data, q), Eigen::EigenvaluesOnly);
      const double cond_M = es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
      if (proj.partition_condition() < 1e3) {
        EXPECT_LE(test::rel_diff(xa.segment(n, n), xo.segment(n, n)), 1e-13 * cond_M + 1e-13)
            << n << " cond(M) = " << cond_M;
      }
    }
  }
}

// Issue 21 item 5: on large models the projection is as accurate as the Lagrange (KKT) route.
// The partitioned basis N = [I; −K_dc⁻¹K_ic] (the fixed-size kernels, n ≤ 4) solves
// (NᵀMN) u = … whose error grows with cond(K_dc)² · cond(M); every other size takes the
// orthonormal basis of the null space of A (Householder QR of Aᵀ), whose error is cond(M)·ε like
// the KKT solve's, whatever the partition. Random 30- and 60-DOF chains, 4 rows (the tip's x, y, z
// held where it is, a joint coupling) or 6 (plus a closed loop: the tip on a point of the middle
// link in x and z), the partition chosen automatically and a deliberately poor one (the largest
// κ = ‖A‖₁‖K_dc⁻¹‖₁ below 1e4 among random dependent sets). Tolerance: |q̈_proj − q̈_lag|∞ ≤
// 1e-10 · max(1, |q̈|∞), i.e. 1e-10 relative to the size of q̈ (absolute below 1): |q̈|∞ reaches
// 1e4 here (random q̇ and Baumgarte terms) and both routes are only determined to about
// cond(M)·ε relative, cond(M) up to 1e6 (measured: 6e-12 relative at 60 DOF). The same bound
// holds for each route against a long-double KKT solve of the same M, F, A, rhs; the test prints
// those errors and the error of the partitioned basis on the same systems (the former route,
// about 5e-9 relative here: it would fail the bound).
TEST(ReferenceDynamics, ProjectionIsAsAccurateAsLagrangeOnLargeChains) {
  using LD = long double;
  using MatL = Eigen::Matrix<LD, Eigen::Dynamic, Eigen::Dynamic>;
  std::mt19937 rng(2105);
  for (int n : {30, 60}) {
    double worst_diff = 0, worst_rel = 0, worst_proj = 0, worst_lag = 0, worst_kappa = 0;
    double worst_partitioned[2] = {0, 0};  // automatic partition, poor partition
    int cases = 0;
    for (int seed = 0; seed < 4; ++seed) {
      test::RandomChainOptions opt;
      opt.dof = n;
      ModelDescription d = test::random_chain(rng, opt);
      d.add_point("mid", d.links[d.links.size() / 2].name, Vec3(0.1, -0.2, 0.15));
      const Model model = build_model(d);
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 1.0);
      Data data(model);
      forward_kinematics(model, data, q);
      const Vec3 tip = point_position(model, data, model.point_index("tip"));
      ConstraintSet set;
      for (int axis = 0; axis < 3; ++axis) set.add(point_coordinate(model, "tip", axis, constant(tip[axis])));
      set.add(joint_coupling(model, model.joint_name[1], model.joint_name[0], 0.5));
      if (seed % 2) set.add(points_coincide(model, "tip", "mid", {0, 2}));
      ForceSet forces;
      forces.add(joint_damping(model, model.joint_name[0], 0.7));
      forces.add(joint_spring(model, model.joint_name[n - 1], 3.0, 0.2));
      ReferenceDynamicsOptions po, lo;
      po.solver = ReferenceSolver::Projection;
      lo.solver = ReferenceSolver::Lagrange;
      ReferenceDynamics lag(model, forces, set, lo);
      const int m = set.rows();
      for (bool poor : {false, true}) {
        ReferenceDynamics proj(model, forces, set, po);
        double kappa = proj.choose_partition(0.1, q, qd);
        if (poor) {  // the worst partition with κ < 1e4 among 300 random dependent sets
          const Eigen::MatrixXd& A = proj.constraints().A;
          const double normA = A.cwiseAbs().colwise().sum().maxCoeff();
          std::vector<int> all(n), best_dep;
          std::iota(all.begin(), all.end(), 0);
          double best = 0;
          for (int trial = 0; trial < 300; ++trial) {
            std::shuffle(all.begin(), all.end(), rng);
            std::vector<int> dep(all.begin(), all.begin() + m);
            Eigen::MatrixXd K(m, m);
            for (int c = 0; c < m; ++c) K.col(c) = A.col(dep[c]);
            Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
            if (!lu.isInvertible()) continue;
            const double kap = normA * lu.inverse().cwiseAbs().colwise().sum().maxCoeff();
            if (kap < 1e4 && kap > best) best = kap, best_dep = dep;
          }
          ASSERT_GT(best, 100.0) << "no poor partition found, n " << n << " seed " << seed;
          std::vector<int> ind;
          for (int i = 0; i < n; ++i)
            if (std::find(best_dep.begin(), best_dep.end(), i) == best_dep.end()) ind.push_back(i);
          proj.set_independent(ind);
          kappa = best;
        }
        const Eigen::VectorXd x = proj.make_state(q, qd);
        Eigen::VectorXd xp(x.size()), xl(x.size());
        proj.derivative(0.1, x, xp);
        lag.derivative(0.1, x, xl);
        EXPECT_NEAR(proj.partition_condition(), kappa, 1e-6 * kappa);  // the partition kept its meaning
        const std::string where = "n " + std::to_string(n) + " rows " + std::to_string(m) + " seed " +
                                  std::to_string(seed) + (poor ? " poor partition, kappa " : " kappa ") +
                                  std::to_string(kappa);
        const double scale = std::max(1.0, lag.qdd().cwiseAbs().maxCoeff());
        const double diff = (proj.qdd() - lag.qdd()).cwiseAbs().maxCoeff();
        EXPECT_LE(diff, 1e-10 * scale) << where;
        EXPECT_TRUE(near(proj.lambda(), lag.lambda(), 1e-9)) << where;
        EXPECT_TRUE(near(proj.constraint_force(), lag.constraint_force(), 1e-9, 1e-9)) << where;
        worst_diff = std::max(worst_diff, diff);
        worst_rel = std::max(worst_rel, diff / scale);
        worst_kappa = std::max(worst_kappa, kappa);
        // Reference: the KKT system of the same M, F, A, rhs in long double.
        const Eigen::MatrixXd& M = proj.mass();
        const Eigen::VectorXd F = proj.applied_force() - proj.bias();
        const Eigen::MatrixXd& A = proj.constraints().A;
        const ConstraintEval& ev = proj.constraints();
        Eigen::VectorXd rhs(m);
        for (int r = 0; r < m; ++r) rhs[r] = -ev.gamma[r] - 2 * po.alpha * ev.phid[r] - po.beta * po.beta * ev.phi[r];
        MatL K = MatL::Zero(n + m, n + m);
        K.topLeftCorner(n, n) = M.cast<LD>();
        K.topRightCorner(n, m) = A.transpose().cast<LD>();
        K.bottomLeftCorner(m, n) = A.cast<LD>();
        Eigen::Matrix<LD, Eigen::Dynamic, 1> b(n + m);
        b << F.cast<LD>(), rhs.cast<LD>();
        const Eigen::VectorXd exact = K.fullPivLu().solve(b).head(n).cast<double>();
        // The partitioned basis on the same system (the route's former algorithm, in Eigen).
        const int k = n - m;
        Eigen::MatrixXd Kdc(m, m), Kic(m, k), N = Eigen::MatrixXd::Zero(n, k);
        for (int c = 0; c < m; ++c) Kdc.col(c) = A.col(proj.dependent()[c]);
        for (int c = 0; c < k; ++c) Kic.col(c) = A.col(proj.independent()[c]);
        const Eigen::MatrixXd Kinv = Kdc.inverse(), G = -Kinv * Kic;
        for (int c = 0; c < k; ++c) {
          N(proj.independent()[c], c) = 1;
          for (int r = 0; r < m; ++r) N(proj.dependent()[r], c) = G(r, c);
        }
        Eigen::VectorXd partitioned = Eigen::VectorXd::Zero(n);
        const Eigen::VectorXd p = Kinv * rhs;
        for (int r = 0; r < m; ++r) partitioned[proj.dependent()[r]] = p[r];
        const Eigen::MatrixXd NMN = N.transpose() * M * N;
        partitioned += N * NMN.llt().solve(N.transpose() * (F - M * partitioned));
        EXPECT_LE((proj.qdd() - exact).cwiseAbs().maxCoeff(), 1e-10 * scale) << where;
        EXPECT_LE((lag.qdd() - exact).cwiseAbs().maxCoeff(), 1e-10 * scale) << where;
        worst_proj = std::max(worst_proj, (proj.qdd() - exact).cwiseAbs().maxCoeff() / scale);
        worst_lag = std::max(worst_lag, (lag.qdd() - exact).cwiseAbs().maxCoeff() / scale);
        worst_partitioned[poor] = std::max(worst_partitioned[poor], (partitioned - exact).cwiseAbs().maxCoeff() / scale);
        ++cases;
      }
    }
    std::cout << "[ projection accuracy ] " << n << " DOF, " << cases << " systems (partition kappa up to " << worst_kappa
              << "): |q̈_proj − q̈_lag|∞ worst " << worst_diff << " (relative to max(1, |q̈|∞): " << worst_rel
              << "); error against a long-double KKT solve, relative to max(1, |q̈|∞): projection " << worst_proj
              << ", Lagrange " << worst_lag << ", the partitioned basis N = [I; −K_dc⁻¹K_ic] " << worst_partitioned[0]
              << " (automatic partitions), " << worst_partitioned[1] << " (poor partitions)\n";
  }
}

// The orthonormal route's edge cases: as many rows as coordinates (no null space, q̈ = A⁻¹ rhs by
// the partition's K_dc⁻¹: 2 rows on 2 coordinates, 5 on 5, where K_dc⁻¹ comes from an LU) and a
// single row on a model outside the fixed-size kernels; projection = Lagrange.
TEST(ReferenceDynamics, OrthonormalRouteWithFullAndSingleRowSets) {
  std::mt19937 rng(2106);
  const Model arm2 = build_model(planar_arm(2));
  ConstraintSet full;  // the tip's x and y: 2 rows on 2 coordinates
  full.add(point_coordinate(arm2, "tip", 0, sinusoid(0.1, 1.0, 0.0, 1.2)));
  full.add(point_coordinate(arm2, "tip", 1, constant(0.8)));
  const Model chain6 = build_model(test::random_chain(rng, {.dof = 6}));
  ConstraintSet single;
  single.add(point_coordinate(chain6, "tip", 2, constant(0.2)));
  const Model chain5 = build_model(test::random_chain(rng, {.dof = 5}));
  ConstraintSet full5;  // four couplings and the tip's height: 5 rows on 5 coordinates
  for (int j = 1; j < 5; ++j) full5.add(joint_coupling(chain5, chain5.joint_name[j], chain5.joint_name[j - 1], 0.5 + 0.1 * j));
  full5.add(point_coordinate(chain5, "tip", 2, sinusoid(0.05, 1.0, 0.0, 0.1)));
  ForceSet forces2, forces6, forces5;
  forces2.add(joint_damping(arm2, "q1", 0.4));
  forces6.add(joint_damping(chain6, chain6.joint_name[2], 0.4));
  forces5.add(joint_damping(chain5, chain5.joint_name[3], 0.4));
  for (auto [model, set, forces] : {std::tuple{&arm2, &full, &forces2}, std::tuple{&chain6, &single, &forces6},
                                    std::tuple{&chain5, &full5, &forces5}}) {
    const int n = model->nq;
    ReferenceDynamicsOptions po, lo;
    po.solver = ReferenceSolver::Projection;
    lo.solver = ReferenceSolver::Lagrange;
    ReferenceDynamics proj(*model, *forces, *set, po), lag(*model, *forces, *set, lo);
    Eigen::VectorXd q = test::random_vector(rng, n, 1.0);
    if (n == 2) q << 0.4, 1.1;  // the arm away from its stretched (singular) pose
    const Eigen::VectorXd qd = test::random_vector(rng, n, 1.0);
    const Eigen::VectorXd x = proj.make_state(q, qd);
    Eigen::VectorXd xp(x.size()), xl(x.size());
    proj.derivative(0.3, x, xp);
    lag.derivative(0.3, x, xl);
    EXPECT_LE((xp - xl).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, xl.cwiseAbs().maxCoeff())) << n;
    EXPECT_TRUE(near(proj.lambda(), lag.lambda(), 1e-10, 1e-12)) << n;
  }
}

// Without constraint rows a large model's reference dynamics takes the articulated-body
// algorithm: exactly forward_dynamics_aba with τ = Q, and Q_c = 0; smaller ones keep the
// projection's Cholesky of M, and both equal CRBA + Cholesky to cond(M)·ε.
TEST(ReferenceDynamics, UnconstrainedLargeModelsUseTheArticulatedBodyAlgorithm) {
  std::mt19937 rng(132);
  for (int n : {kAbaFrom - 1, kAbaFrom, 40}) {
    for (bool tree : {false, true}) {
      test::RandomChainOptions opt;
      opt.dof = n;
      opt.tree = tree;
      const Model model = build_model(test::random_chain(rng, opt));
      ConstraintSet none;
      ForceSet forces;
      forces.add(joint_damping(model, model.joint_name[0], 0.7));
      forces.add(joint_spring(model, model.joint_name[n - 1], 3.0, 0.2));
      for (ReferenceSolver solver : {ReferenceSolver::Projection, ReferenceSolver::Lagrange}) {
        ReferenceDynamicsOptions o;
        o.solver = solver;
        ReferenceDynamics rd(model, forces, none, o);
        const Eigen::VectorXd q = test::random_vector(rng, n, 2.0), qd = test::random_vector(rng, n, 1.0);
        const Eigen::VectorXd x = rd.make_state(q, qd);
        Eigen::VectorXd xdot(x.size());
        rd.derivative(0.2, x, xdot);
        Data data(model);
        const Eigen::VectorXd Q = rd.applied_force();
        const Eigen::VectorXd crba = forward_dynamics_crba(model, data, q, qd, Q);
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(data.M, Eigen::EigenvaluesOnly);
        const double cond = es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
        EXPECT_LE(test::rel_diff(rd.qdd(), crba), 1e-13 * cond + 1e-13) << n;
        if (forward_dynamics_uses_aba(n)) {
          EXPECT_EQ(rd.qdd(), forward_dynamics_aba(model, data, q, qd, Q)) << n;  // bit for bit
          EXPECT_EQ(rd.constraint_force(), Eigen::VectorXd::Zero(n)) << n;
        }
        EXPECT_TRUE(near(xdot.head(n), qd, 0, 0));
      }
    }
  }
}

namespace {
// The partition tests' mechanism: a random 6-DOF chain with a point "mid" on link 3, the tip held
// to it in x and z and guided as a knife edge along y (3 rows), damping on q2.
Model chain_with_mid(std::mt19937& rng) {
  ModelDescription d = test::random_chain(rng, {.dof = 6});
  d.add_point("mid", d.links[3].name, Vec3(0.1, -0.2, 0.15));
  return build_model(d);
}
void add_tip_to_mid(const Model& model, ConstraintSet& set, ForceSet& forces) {
  set.add(points_coincide(model, "tip", "mid", {0, 2}));
  set.add(knife_edge(model, "tip", Vec3(0, 1, 0)));
  forces.add(joint_damping(model, "q2", 0.5));
}
}  // namespace

TEST(ReferenceDynamics, AnyValidPartitionGivesTheSameAcceleration) {
  std::mt19937 rng(42);
  const Model model = chain_with_mid(rng);
  ConstraintSet set;
  ForceSet forces;
  add_tip_to_mid(model, set, forces);
  ReferenceDynamics rd(model, forces, set);
  const Eigen::VectorXd q = test::random_vector(rng, 6, 2.0), qd = test::random_vector(rng, 6, 1.0);
  Eigen::VectorXd x = rd.make_state(q, qd), xdot(x.size());
  rd.choose_partition(0.3, q, qd);
  rd.derivative(0.3, x, xdot);
  const Eigen::VectorXd ref = rd.qdd();
  int tried = 0;
  // Every 3-subset as dependent coordinates, where K_dc is reasonably conditioned.
  for (int a = 0; a < 6; ++a)
    for (int b = a + 1; b < 6; ++b)
      for (int c = b + 1; c < 6; ++c) {
        std::vector<int> ind;
        for (int i = 0; i < 6; ++i)
          if (i != a && i != b && i != c) ind.push_back(i);
        rd.set_independent(ind);
        try {
          rd.derivative(0.3, x, xdot);
        } catch (const NumericalFailure&) {
          continue;
        }
        if (rd.partition_condition() > 1e3) continue;
        EXPECT_TRUE(near(rd.qdd(), ref, 1e-9)) << "dependent " << a << b << c;
        EXPECT_EQ(rd.dependent(), (std::vector<int>{a, b, c}));
        ++tried;
      }
  EXPECT_GE(tried, 10);
}

// The orthonormal route (6 coordinates, 4 rows) does not use the partition: every choice of
// dependent coordinates, singular K_dc included, gives the same q̈ and λ bit for bit, and
// partition_condition() still reports κ = ‖A‖₁‖K_dc⁻¹‖₁ of the chosen partition (computed when
// asked). Dependent rows are what stops it: a repeated row is a NumericalFailure naming the rows.
TEST(Partition, TheOrthonormalRouteDoesNotDependOnThePartition) {
  std::mt19937 rng(42);
  const Model model = chain_with_mid(rng);
  ConstraintSet set;
  ForceSet forces;
  add_tip_to_mid(model, set, forces);
  set.add(joint_trajectory(model, "q3", polynomial({0.2, 0.5})));  // a row e_3: K_dc singular unless q3 is dependent
  ReferenceDynamicsOptions po;
  po.solver = ReferenceSolver::Projection;
  ReferenceDynamics rd(model, forces, set, po);
  ReferenceDynamicsOptions lo;
  lo.solver = ReferenceSolver::Lagrange;
  ReferenceDynamics lag(model, forces, set, lo);
  const Eigen::VectorXd q = test::random_vector(rng, 6, 2.0), qd = test::random_vector(rng, 6, 1.0);
  Eigen::VectorXd x = rd.make_state(q, qd), xdot(x.size()), xl(x.size());
  rd.choose_partition(0.3, q, qd);
  rd.derivative(0.3, x, xdot);
  lag.derivative(0.3, x, xl);
  const Eigen::VectorXd ref = rd.qdd(), ref_lambda = rd.lambda();
  EXPECT_TRUE(near(ref, lag.qdd(), 1e-10, 1e-12));
  EXPECT_TRUE(near(ref_lambda, lag.lambda(), 1e-10, 1e-12));
  const Eigen::MatrixXd A = rd.constraints().A;
  int singular = 0, sets = 0;
  for (int a = 0; a < 6; ++a)  // every pair of independent coordinates
    for (int b = a + 1; b < 6; ++b) {
      const std::string label = "independent " + std::to_string(a) + std::to_string(b);
      rd.set_independent({a, b});
      ASSERT_NO_THROW(rd.derivative(0.3, x, xdot)) << label;
      EXPECT_EQ(rd.qdd(), ref) << label;
      EXPECT_EQ(rd.lambda(), ref_lambda) << label;
      Eigen::Matrix4d K;
      for (int c = 0; c < 4; ++c) K.col(c) = A.col(rd.dependent()[c]);
      const Eigen::FullPivLU<Eigen::Matrix4d> lu(K);
      const double kappa = lu.isInvertible() ? A.cwiseAbs().colwise().sum().maxCoeff() *
                                                   lu.inverse().cwiseAbs().colwise().sum().maxCoeff()
                                             : std::numeric_limits<double>::infinity();
      const double reported = rd.partition_condition();
      if (a == 2 || b == 2) {  // q3 independent: its row has no dependent entry
        EXPECT_GT(reported, 1e12) << label;
        ++singular;
      } else {
        EXPECT_NEAR(reported, kappa, 1e-8 * kappa) << label;
      }
      ++sets;
    }
  EXPECT_EQ(sets, 15);
  EXPECT_EQ(singular, 5);
  std::cout << "[ partition ] orthonormal route: " << sets << " partitions (" << singular
            << " with kappa > 1e8) give the same bits\n";

  auto again = points_coincide(model, "tip", "mid", {0});  // the first row once more (5 rows)
  again->name = "again";
  set.add(again);
  ReferenceDynamics dep(model, forces, set, po);
  Eigen::VectorXd x4 = dep.make_state(q, qd), xdot4(x4.size());
  try {
    dep.derivative(0.3, x4, xdot4);
    ADD_FAILURE() << "expected NumericalFailure for a repeated row";
  } catch (const NumericalFailure& e) {
    const std::string msg = e.what();
    for (const char* needle : {"t = 0.3", "dependent", "again", "max_condition"})
      EXPECT_NE(msg.find(needle), std::string::npos) << "'" << needle << "' not in: " << msg;
  }
}

// ================================================================ (b) Baumgarte decay

namespace {

struct DecayCase {
  std::string label;
  double alpha, beta;
  std::function<double(double)> shape;  // Φ(t)/Φ(0) for Φ(0) ≠ 0, Φ̇(0) = 0
};

std::vector<DecayCase> decay_cases() {
  return {
      // s² + 10 s + 16 = (s + 2)(s + 8)
      {"overdamped (-2, -8)", 5.0, 4.0, [](double t) { return (8 * std::exp(-2 * t) - 2 * std::exp(-8 * t)) / 6; }},
      // s² + 6 s + 9 = (s + 3)²
      {"critical (-3, -3)", 3.0, 3.0, [](double t) { return (1 + 3 * t) * std::exp(-3 * t); }},
      // s² + 2 s + 25: −1 ± i√24
      {"underdamped (-1 ± i√24)", 1.0, 5.0,
       [](double t) {
         const double w = std::sqrt(24.0);
         return std::exp(-t) * (std::cos(w * t) + std::sin(w * t) / w);
       }},
  };
}

}  // namespace

TEST(Baumgarte, HolonomicErrorFollowsTheClosedFormOfTheStabilizationLaw) {
  // A planar 2R arm whose tip must stay on a line x = c (linear in the point) or on a circle,
  // started off the constraint with zero velocity; a torque on joint 1 keeps it moving along
  // the constraint. Φ̈ = A q̈ + γ holds exactly, so Φ̈ + 2αΦ̇ + β²Φ = 0 exactly.
  const Model model = build_model(planar_arm(2));
  Eigen::VectorXd q0(2);
  q0 << 0.3, 1.2;
  const double x0 = std::cos(0.3) + std::cos(1.5), y0 = std::sin(0.3) + std::sin(1.5);
  const double delta = 0.01;
  ForceSet forces;
  forces.add(joint_effort(model, "q1", constant(0.5)));
  struct Geometry {
    std::string label;
    ConstraintPtr c;
  };
  const std::vector<Geometry> geometries{
      {"line", point_coordinate(model, "tip", 0, constant(x0 - delta))},
      {"circle", point_on_surface(model, "tip", elliptic_cylinder(1.2, 1.2, x0 - 1.2 - delta, y0))},
  };
  for (const Geometry& g : geometries) {
    for (const DecayCase& dc : decay_cases()) {
      ConstraintSet set;
      set.add(g.c);
      ReferenceDynamicsOptions o;
      o.alpha = dc.alpha;
      o.beta = dc.beta;
      o.automatic_partition = true;
      ReferenceDynamics rd(model, forces, set, o);
      Eigen::VectorXd x = rd.make_state(q0, Eigen::VectorXd::Zero(2));
      Residuals phi(model, set);
      const double phi0 = phi(0.0, x)[0];
      ASSERT_GT(std::abs(phi0), 1e-3) << g.label;
      IntegratorOptions io = rk4(2.0, 1e-4);
      io.output_interval = 0.01;
      double worst = 0;
      int samples = 0;
      auto s = run(rd, x, io, [&](double t, const Eigen::VectorXd& xx) {
        worst = std::max(worst, std::abs(phi(t, xx)[0] - phi0 * dc.shape(t)));
        ++samples;
        return true;
      });
      ASSERT_TRUE(s.ok()) << s.message;
      EXPECT_EQ(samples, 201);
      EXPECT_LT(worst, 1e-6 * std::abs(phi0)) << g.label << ", " << dc.label;
      // The arm did move along the constraint (not a trivial test).
      EXPECT_GT(std::abs(x[0] - q0[0]), 0.05) << g.label << ", " << dc.label;
      std::cout << "[ Baumgarte ] " << g.label << ", " << dc.label << ": Φ(0) = " << phi0
                << ", max |Φ − Φ_exact| / |Φ(0)| = " << worst / std::abs(phi0) << "\n";
    }
  }
}

TEST(Baumgarte, FirstOrderRowsDecayExponentiallyAlongsideHolonomicRows) {
  // Planar 3R arm: tip y held at a height (holonomic, started δ off) and the tip's speed towards
  // the base prescribed (first order, started at rest: c(0) = −s0). With β₁ = 3:
  // c(t) = −s0 e^(−3t). (Moving towards the base keeps the arm away from its reach limit.)
  const Model model = build_model(planar_arm(3));
  Eigen::VectorXd q0(3);
  q0 << 0.2, 0.9, -0.6;
  Data d0(model);
  forward_kinematics(model, d0, q0);
  const double y0 = point_position(model, d0, model.point_index("tip")).y();
  const double delta = -0.02, s0 = 0.3;
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 1, constant(y0 - delta)));
  set.add(point_speed(model, "tip", -Vec3::UnitX(), constant(s0)));
  ForceSet forces;
  ReferenceDynamicsOptions o;
  o.alpha = 5.0;
  o.beta = 4.0;
  o.beta_first_order = 3.0;
  o.automatic_partition = true;
  ReferenceDynamics rd(model, forces, set, o);
  Eigen::VectorXd x = rd.make_state(q0, Eigen::VectorXd::Zero(3));
  Residuals phi(model, set);
  EXPECT_NEAR(phi(0.0, x)[0], delta, 1e-15);
  EXPECT_NEAR(phi(0.0, x)[1], -s0, 1e-15);
  IntegratorOptions io = rk4(1.5, 1e-4);
  io.output_interval = 0.01;
  double worst_h = 0, worst_f = 0;
  auto s = run(rd, x, io, [&](double t, const Eigen::VectorXd& xx) {
    const Eigen::VectorXd& p = phi(t, xx);
    worst_h = std::max(worst_h, std::abs(p[0] - delta * (8 * std::exp(-2 * t) - 2 * std::exp(-8 * t)) / 6));
    worst_f = std::max(worst_f, std::abs(p[1] + s0 * std::exp(-3 * t)));
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.message;
  EXPECT_LT(worst_h, 1e-6 * std::abs(delta));
  EXPECT_LT(worst_f, 1e-6 * s0);
  std::cout << "[ Baumgarte ] mixed: holonomic max error / |Φ(0)| = " << worst_h / std::abs(delta)
            << ", first-order max |c − c0 e^(−β₁t)| / |c0| = " << worst_f / s0 << "\n";
}

TEST(Baumgarte, KnifeEdgeViolationDecaysExponentially) {
  // A planar 3R arm with a knife edge at the tip (lateral axis: the last link's y axis), started
  // with a random velocity that violates it.
  const Model model = build_model(planar_arm(3));
  ConstraintSet set;
  set.add(knife_edge(model, "tip", Vec3::UnitY()));
  ForceSet forces;
  forces.add(joint_effort(model, "q2", constant(0.3)));
  ReferenceDynamicsOptions o;
  o.beta_first_order = 4.0;
  o.automatic_partition = true;
  ReferenceDynamics rd(model, forces, set, o);
  Eigen::VectorXd q0(3), qd0(3);
  q0 << 0.1, 0.7, -0.4;
  qd0 << 0.3, -0.5, 0.8;
  Eigen::VectorXd x = rd.make_state(q0, qd0);
  Residuals phi(model, set);
  const double c0 = phi(0.0, x)[0];
  ASSERT_GT(std::abs(c0), 0.1);
  IntegratorOptions io = rk4(1.5, 1e-4);
  io.output_interval = 0.01;
  double worst = 0;
  auto s = run(rd, x, io, [&](double t, const Eigen::VectorXd& xx) {
    worst = std::max(worst, std::abs(phi(t, xx)[0] - c0 * std::exp(-4 * t)));
    return true;
  });
  ASSERT_TRUE(s.ok()) << s.message;
  EXPECT_LT(worst, 1e-6 * std::abs(c0));
  std::cout << "[ Baumgarte ] knife edge: c(0) = " << c0 << ", max |c − c0 e^(−β₁t)| / |c0| = " << worst / std::abs(c0)
            << "\n";
}

// ================================================================ (c) rheonomic closed form

TEST(ClosedForm, BeadOnASpinningWire) {
  // Wire spun at ω by a joint trajectory, no force along the wire: r̈ = ω² r, so a bead released
  // at rest relative to the wire at r0 moves as r = r0 cosh(ωt). The torque that keeps ω
  // constant is d/dt(∂L/∂θ̇) = 2 m r ṙ ω.
  const double mb = 0.7, w = 2.0, r0 = 0.3, t1 = 1.5;
  const Model model = build_model(bead_on_wire(mb));
  ConstraintSet set;
  set.add(joint_trajectory(model, "spin", polynomial({0.0, w})));
  ForceSet forces;
  for (ReferenceSolver solver : {ReferenceSolver::Projection, ReferenceSolver::Lagrange}) {
    for (IntegratorMethod method : {IntegratorMethod::RK4, IntegratorMethod::DormandPrince45}) {
      ReferenceDynamicsOptions o;
      o.solver = solver;
      ReferenceDynamics rd(model, forces, set, o);
      Eigen::VectorXd q(2), qd(2);
      q << 0.0, r0;
      qd << w, 0.0;
      Eigen::VectorXd x = rd.make_state(q, qd);
      IntegratorOptions io = rk4(t1, 1e-4);
      io.method = method;
      io.rtol = 1e-12;
      io.atol = 1e-14;
      auto s = run(rd, x, io);
      ASSERT_TRUE(s.ok()) << s.message;
      const double r = r0 * std::cosh(w * t1), rd_exact = r0 * w * std::sinh(w * t1);
      const std::string where = std::string(solver == ReferenceSolver::Projection ? "projection" : "lagrange") +
                                ", " + to_string(method);
      EXPECT_NEAR(x[1], r, 1e-8 * r) << where;
      EXPECT_NEAR(x[3], rd_exact, 1e-8 * rd_exact) << where;
      EXPECT_NEAR(x[0], w * t1, 1e-10) << where;
      EXPECT_NEAR(x[2], w, 1e-10) << where;
      Eigen::VectorXd xdot(x.size());
      rd.derivative(t1, x, xdot);
      const double torque = 2 * mb * r * rd_exact * w;
      EXPECT_NEAR(rd.constraint_force()[0], torque, 1e-8 * torque) << where;
      EXPECT_NEAR(rd.constraint_force()[1], 0.0, 1e-9) << where;
      std::cout << "[ bead ] " << where << ": r error " << x[1] - r << " (r = " << r << "), torque error "
                << rd.constraint_force()[0] - torque << "\n";
    }
  }
}

// ================================================================ (d) nonholonomic closed form

TEST(ClosedForm, KnifeEdgeDrivenByYawTorqueAndForwardForce) {
  // Blade at the centre of mass: J θ̈ = τ (the lateral reaction has no moment) and m u̇ = F for
  // the speed u along the heading; the lateral reaction is m u θ̇.
  const double m = 2.0, J = 0.3, tau = 0.6, F = 0.8;
  const double th0 = 0.3, om0 = 0.5, u0 = 1.0, t1 = 2.0;
  const Model model = build_model(sleigh(m, J));
  ConstraintSet set;
  set.add(knife_edge(model, "P", Vec3::UnitY()));
  ForceSet forces;
  forces.add(joint_effort(model, "theta", constant(tau)));
  forces.add(std::make_shared<ForwardForce>(F));
  auto theta = [&](double t) { return th0 + om0 * t + 0.5 * tau / J * t * t; };
  auto speed = [&](double t) { return u0 + F / m * t; };
  // x(t1), y(t1) = ∫ u (cos θ, sin θ) dt by composite Simpson (error ≪ 1e-12 with 20000 panels).
  Eigen::Vector2d pos_exact = Eigen::Vector2d::Zero();
  {
    const int N = 20000;
    const double h = t1 / N;
    for (int i = 0; i <= N; ++i) {
      const double t = i * h, wgt = (i == 0 || i == N) ? 1 : (i % 2 ? 4 : 2);
      pos_exact += wgt * speed(t) * Eigen::Vector2d(std::cos(theta(t)), std::sin(theta(t)));
    }
    pos_exact *= h / 3;
  }
  for (ReferenceSolver solver : {ReferenceSolver::Projection, ReferenceSolver::Lagrange}) {
    ReferenceDynamicsOptions o;
    o.solver = solver;
    o.automatic_partition = true;
    ReferenceDynamics rd(model, forces, set, o);
    Eigen::VectorXd q(3), qd(3);
    q << 0.0, 0.0, th0;
    qd << u0 * std::cos(th0), u0 * std::sin(th0), om0;
    Eigen::VectorXd x = rd.make_state(q, qd);
    double worst_c = 0, worst_theta = 0, worst_u = 0;
    Residuals phi(model, set);
    IntegratorOptions io = rk4(t1, 2.5e-4);
    io.output_interval = 0.01;
    auto s = run(rd, x, io, [&](double t, const Eigen::VectorXd& xx) {
      worst_c = std::max(worst_c, std::abs(phi(t, xx)[0]));
      worst_theta = std::max(worst_theta, std::abs(xx[2] - theta(t)));
      const double u = xx[3] * std::cos(xx[2]) + xx[4] * std::sin(xx[2]);
      worst_u = std::max(worst_u, std::abs(u - speed(t)));
      return true;
    });
    ASSERT_TRUE(s.ok()) << s.message;
    const std::string where = solver == ReferenceSolver::Projection ? "projection" : "lagrange";
    EXPECT_LT(worst_theta, 1e-8) << where;
    EXPECT_LT(worst_u, 1e-8) << where;
    EXPECT_LT(worst_c, 1e-10) << where;
    EXPECT_NEAR(x[5], om0 + tau / J * t1, 1e-8) << where;
    EXPECT_TRUE(near(x.head(2), pos_exact, 1e-8, 1e-8)) << where;
    // The lateral reaction.
    Eigen::VectorXd xdot(x.size());
    rd.derivative(t1, x, xdot);
    const double lat = m * speed(t1) * (om0 + tau / J * t1);
    Eigen::Vector3d Qc_exact(-std::sin(theta(t1)) * lat, std::cos(theta(t1)) * lat, 0.0);
    EXPECT_TRUE(near(rd.constraint_force(), Qc_exact, 1e-8, 1e-8)) << where;
    std::cout << "[ knife edge ] " << where << ": max |θ − θ_exact| " << worst_theta << ", max |u − u_exact| "
              << worst_u << ", max |c| " << worst_c << ", |pos − pos_exact| " << (x.head(2) - pos_exact).norm() << "\n";
  }
}

// ================================================================ (e) partitions

TEST(Partition, SingularPartitionIsANumericalFailureNamingTimeConstraintsCoordinatesAndCondition) {
  const Model model = build_model(bead_on_wire(0.7));
  ConstraintSet set;
  set.add(joint_trajectory(model, "spin", polynomial({0.0, 2.0})));
  ForceSet forces;
  ReferenceDynamicsOptions o;
  o.independent = {"spin"};  // the constrained coordinate itself: K_dc = ∂Φ/∂(bead) = 0
  Eigen::VectorXd q(2), qd(2);
  q << 0.5, 0.3;
  qd << 2.0, 0.0;
  {
    ReferenceDynamics rd(model, forces, set, o);
    Eigen::VectorXd x = rd.make_state(q, qd), xdot(x.size());
    try {
      rd.derivative(0.25, x, xdot);
      ADD_FAILURE() << "expected NumericalFailure";
    } catch (const NumericalFailure& e) {
      EXPECT_EQ(e.time, 0.25);
      const std::string msg = e.what();
      for (const char* needle : {"t = 0.25", "q_spin", "[bead]", "condition number"})
        EXPECT_NE(msg.find(needle), std::string::npos) << "'" << needle << "' not in: " << msg;
    }
    // Through the integrator: status NumericalFailure with the same message, state kept.
    Eigen::VectorXd x0 = x;
    auto s = run(rd, x, rk4(1.0, 1e-3, 0.25));
    EXPECT_EQ(s.status, IntegrationStatus::NumericalFailure);
    EXPECT_NE(s.message.find("t = 0.25"), std::string::npos) << s.message;
    EXPECT_NE(s.message.find("q_spin"), std::string::npos) << s.message;
    EXPECT_EQ(x, x0);
    EXPECT_EQ(s.t_end, 0.25);
  }
  {
    o.automatic_partition = true;
    ReferenceDynamics rd(model, forces, set, o);
    Eigen::VectorXd x = rd.make_state(q, qd);
    auto s = run(rd, x, rk4(1.25, 1e-4, 0.25));
    ASSERT_TRUE(s.ok()) << s.message;
    EXPECT_EQ(rd.independent(), std::vector<int>{1});
    EXPECT_EQ(rd.dependent(), std::vector<int>{0});
    EXPECT_NEAR(x[1], 0.3 * std::cosh(2.0), 1e-8 * 0.3 * std::cosh(2.0));
  }
}

TEST(Partition, RankDeficientConstraintsAreReportedAsNumericalFailure) {
  // A planar arm's tip cannot leave its plane: the row of "z_tip = 0" is identically zero, so
  // no dependent set has a regular K_dc. Choosing a partition must report that (naming the
  // time and the constraints), not fail with an unrelated size error, and an integration with
  // an automatic partition must end with status NumericalFailure rather than throw.
  const Model model = build_model(planar_arm(2));
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 2, constant(0.0)));
  ForceSet forces;
  Eigen::VectorXd q(2), qd = Eigen::VectorXd::Zero(2);
  q << 0.3, 0.8;
  {
    ReferenceDynamics rd(model, forces, set);
    try {
      rd.choose_partition(0.5, q, qd);
      ADD_FAILURE() << "expected NumericalFailure from choose_partition";
    } catch (const NumericalFailure& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("t = 0.5"), std::string::npos) << msg;
      EXPECT_NE(msg.find("z_tip"), std::string::npos) << msg;
    } catch (const Error& e) {
      ADD_FAILURE() << "choose_partition threw a plain Error instead of NumericalFailure: " << e.what();
    }
  }
  {
    ReferenceDynamics rd(model, forces, set);  // automatic partition at the first evaluation
    Eigen::VectorXd x = rd.make_state(q, qd);
    IntegrationSummary s;
    try {
      s = run(rd, x, rk4(1.5, 1e-3, 0.5));
    } catch (const std::exception& e) {
      FAIL() << "integrate threw instead of reporting: " << e.what();
    }
    EXPECT_EQ(s.status, IntegrationStatus::NumericalFailure) << s.message;
    EXPECT_NE(s.message.find("z_tip"), std::string::npos) << s.message;
  }
  {  // The Lagrange solver reports the same situation as a NumericalFailure already.
    ReferenceDynamicsOptions o;
    o.solver = ReferenceSolver::Lagrange;
    ReferenceDynamics rd(model, forces, set, o);
    Eigen::VectorXd x = rd.make_state(q, qd);
    auto s = run(rd, x, rk4(1.5, 1e-3, 0.5));
    EXPECT_EQ(s.status, IntegrationStatus::NumericalFailure) << s.message;
    EXPECT_NE(s.message.find("t = 0.5"), std::string::npos) << s.message;
  }
}

TEST(Partition, SetIndependentValidatesItsArgument) {
  const Model model = build_model(planar_arm(4));
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 0, constant(1.0)));
  ForceSet forces;
  ReferenceDynamics rd(model, forces, set);
  expect_error_mentioning([&] { rd.set_independent({0, 1}); }, {"independent", "expected 3", "got 2", "q1"});
  expect_error_mentioning([&] { rd.set_independent({0, 1, 2, 3}); }, {"expected 3", "got 4"});
  expect_error_mentioning([&] { rd.set_independent({0, 1, 7}); }, {"index", "7"});
  expect_error_mentioning([&] { rd.set_independent({0, 1, 1}); }, {"q2", "twice"});
  rd.set_independent({3, 0, 2});
  EXPECT_EQ(rd.dependent(), std::vector<int>{1});
  ReferenceDynamicsOptions o;
  o.independent = {"q1", "q3"};
  expect_error_mentioning([&] { ReferenceDynamics(model, forces, set, o); }, {"expected 3", "got 2"});
  o.independent = {"q1", "q3", "qq4"};
  expect_error_mentioning([&] { ReferenceDynamics(model, forces, set, o); }, {"qq4", "did you mean 'q4'"});
}

TEST(Partition, ChoosePartitionPrefersTheWellConditionedDependentSet) {
  // 2R arm, tip on the line x = c, at a configuration where the second link is almost parallel
  // to the line's normal... i.e. ∂x/∂q2 = −sin(q1 + q2) ≈ 1e-9 while ∂x/∂q1 = −y ≈ −1.3:
  // q2 must not be the dependent coordinate (dq2/dq1 = −K_ic/K_dc ≈ 1e9).
  const Model model = build_model(planar_arm(2));
  ConstraintSet set;
  Eigen::VectorXd q(2), qd = Eigen::VectorXd::Zero(2);
  q << 1.2, -1.2 + 1e-9;
  set.add(point_coordinate(model, "tip", 0, constant(std::cos(1.2) + 1.0)));
  ForceSet forces;
  ReferenceDynamics rd(model, forces, set);
  rd.choose_partition(0.0, q, qd);
  EXPECT_EQ(rd.dependent(), std::vector<int>{0}) << "chose dependent q" << rd.dependent()[0] + 1
                                                  << " with cond " << rd.partition_condition();
  // And a fixed partition with that near-singular K_dc is reported, not silently used.
  ReferenceDynamicsOptions o;
  o.independent = {"q1"};
  ReferenceDynamics bad(model, forces, set, o);
  Eigen::VectorXd x = bad.make_state(q, qd), xdot(x.size());
  EXPECT_THROW(bad.derivative(0.0, x, xdot), NumericalFailure)
      << "K_dc = " << -std::sin(1e-9) << " vs K_ic = " << -(std::sin(1.2) + std::sin(1e-9))
      << " accepted with partition_condition() = " << bad.partition_condition();
}

TEST(Partition, AutomaticPartitionCarriesTheRunThroughAPartitionSingularity) {
  // 2R arm (links 1 m), tip on the line x = 0.5, torque on joint 1. Starting with q1
  // independent, the motion reaches q1 = 2π/3 where link 2 is aligned with the line's normal
  // (∂x/∂q2 = −sin(q1 + q2) = 0): q1 cannot parametrize the motion there. With an automatic
  // partition the run continues on q2, and agrees with the Lagrange solution.
  const Model model = build_model(planar_arm(2));
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 0, constant(0.5)));
  ForceSet forces;
  forces.add(joint_effort(model, "q1", constant(1.0)));
  const double q1 = std::numbers::pi / 2 + 0.4, q12 = std::acos(0.5 - std::cos(q1));
  Eigen::VectorXd q(2), qd = Eigen::VectorXd::Zero(2);
  q << q1, q12 - q1;
  const double t1 = 1.5;

  ReferenceDynamicsOptions lo;
  lo.solver = ReferenceSolver::Lagrange;
  ReferenceDynamics lag(model, forces, set, lo);
  Eigen::VectorXd xl = lag.make_state(q, qd);
  double min_sin = 1, max_q1 = -10;
  auto sl = run(lag, xl, rk4(t1, 1e-4), [&](double, const Eigen::VectorXd& x) {
    min_sin = std::min(min_sin, std::sin(x[0] + x[1]));
    max_q1 = std::max(max_q1, x[0]);
    return true;
  });
  ASSERT_TRUE(sl.ok()) << sl.message;
  ASSERT_LT(min_sin, -0.05) << "the reference run must cross the singular configuration";
  EXPECT_NEAR(max_q1, 2 * std::numbers::pi / 3, 1e-4);

  ReferenceDynamicsOptions po;
  po.independent = {"q1"};
  po.automatic_partition = true;
  po.max_condition = 1e3;  // the RK4 stages straddle the singular point: make the switch certain
  ReferenceDynamics proj(model, forces, set, po);
  Eigen::VectorXd xp = proj.make_state(q, qd);
  auto sp = run(proj, xp, rk4(t1, 1e-4));
  ASSERT_TRUE(sp.ok()) << sp.message;
  EXPECT_TRUE(near(xp, xl, 1e-8, 1e-8));
  std::cout << "[ partition ] through the singularity: |x_projection − x_lagrange| = " << (xp - xl).cwiseAbs().maxCoeff()
            << "\n";
}

TEST(Partition, IllConditionedPartitionIsDetectedMidRun) {
  // The same run as above. Near q1 = 2π/3, K_dc = ∂x/∂q2 = −sin(q1 + q2) → 0 while
  // K_ic = ∂x/∂q1 ≈ −1.37: the RK4 stages come within ~1e-4 of the singular point, where
  // ∂q̇_dc/∂q̇_ic = −K_dc⁻¹K_ic ≳ 1e4. With max_condition = 1e3 the fixed partition must stop
  // with a NumericalFailure and the automatic one must switch to q2 as independent coordinate.
  const Model model = build_model(planar_arm(2));
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 0, constant(0.5)));
  ForceSet forces;
  forces.add(joint_effort(model, "q1", constant(1.0)));
  const double q1 = std::numbers::pi / 2 + 0.4, q12 = std::acos(0.5 - std::cos(q1));
  Eigen::VectorXd q(2), qd = Eigen::VectorXd::Zero(2);
  q << q1, q12 - q1;
  const double t1 = 1.5;
  ReferenceDynamicsOptions po;
  po.independent = {"q1"};
  po.max_condition = 1e3;
  double worst_ratio = 0;  // max |K_ic / K_dc| seen by the solver
  {
    ReferenceDynamics fixed(model, forces, set, po);
    Eigen::VectorXd xf = fixed.make_state(q, qd);
    auto sf = integrate(
        [&](double t, const Eigen::VectorXd& xx, Eigen::VectorXd& dx) {
          fixed.derivative(t, xx, dx);
          const Eigen::MatrixXd& A = fixed.constraints().A;
          worst_ratio = std::max(worst_ratio, std::abs(A(0, 0) / A(0, 1)));
        },
        xf, rk4(t1, 1e-4));
    EXPECT_EQ(sf.status, IntegrationStatus::NumericalFailure)
        << to_string(sf.status) << ": " << sf.message << " (max |K_ic/K_dc| met = " << worst_ratio
        << ", partition_condition() = " << fixed.partition_condition() << ")";
    EXPECT_LT(sf.t_end, t1);
    EXPECT_NE(sf.message.find("condition number"), std::string::npos) << sf.message;
  }
  {
    po.automatic_partition = true;
    ReferenceDynamics proj(model, forces, set, po);
    Eigen::VectorXd xp = proj.make_state(q, qd);
    auto sp = run(proj, xp, rk4(t1, 1e-4));
    ASSERT_TRUE(sp.ok()) << sp.message;
    EXPECT_EQ(proj.independent(), std::vector<int>{1}) << "the partition was never re-chosen";
  }
}

// ================================================================ (f) paper-literal forces

// Paper-literal forces on the orthonormal route (6 coordinates): the solve's own multipliers
// belong to f = F + (∂Q/∂q̇)ᵀq̇, and λ is corrected to the least-squares solution of
// Aᵀλ = −Q_c = F − M q̈ (which is not in the range of Aᵀ when Q depends on q̇). Checked against
// Eigen's least squares on Aᵀ.
TEST(PaperLiteralForces, OrthonormalRouteMultipliersBelongToTheConstraintForce) {
  std::mt19937 rng(77);
  ModelDescription d = test::random_chain(rng, {.dof = 6});
  const Model model = build_model(d);
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 0, constant(0.2)));
  set.add(point_coordinate(model, "tip", 2, constant(0.1)));
  ForceSet forces;
  for (int j = 0; j < 6; ++j) forces.add(joint_damping(model, model.joint_name[j], 0.3 + 0.1 * j));
  ReferenceDynamicsOptions o;
  o.solver = ReferenceSolver::Projection;
  o.paper_literal_forces = true;
  ReferenceDynamics rd(model, forces, set, o);
  const Eigen::VectorXd q = test::random_vector(rng, 6, 2.0), qd = test::random_vector(rng, 6, 1.5);
  Eigen::VectorXd x = rd.make_state(q, qd), xdot(x.size());
  rd.derivative(0.1, x, xdot);
  const Eigen::MatrixXd& A = rd.constraints().A;
  const Eigen::VectorXd ls = A.transpose().colPivHouseholderQr().solve(Eigen::VectorXd(-rd.constraint_force()));
  EXPECT_TRUE(near(rd.lambda(), ls, 1e-9, 1e-12)) << rd.lambda().transpose() << " vs " << ls.transpose();
  // The case is one where the correction matters: −Q_c is off the range of Aᵀ by (∂Q/∂q̇)ᵀq̇'s
  // share (without the correction this test fails, checked by removing it).
  EXPECT_GT((A.transpose() * ls + rd.constraint_force()).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(PaperLiteralForces, DifferOnlyWithVelocityDependentForces) {
  const double mb = 0.7, b = 0.4;
  const Model model = build_model(bead_on_wire(mb));
  ConstraintSet set;
  set.add(joint_trajectory(model, "spin", polynomial({0.0, 2.0})));
  Eigen::VectorXd q(2), qd(2);
  q << 0.4, 0.3;
  qd << 2.0, 0.6;
  auto qdd_with = [&](const ForceSet& forces, bool literal) {
    ReferenceDynamicsOptions o;
    o.paper_literal_forces = literal;
    ReferenceDynamics rd(model, forces, set, o);
    Eigen::VectorXd x = rd.make_state(q, qd), xdot(x.size());
    rd.derivative(0.2, x, xdot);
    EXPECT_EQ(rd.dependent(), std::vector<int>{0});
    return Eigen::VectorXd(rd.qdd());
  };
  {  // Viscous damping on the bead: paper-literal adds (∂Q/∂q̇)ᵀq̇ = −b ṙ once more.
    ForceSet damped;
    damped.add(joint_damping(model, "bead", b));
    const Eigen::VectorXd a = qdd_with(damped, false), l = qdd_with(damped, true);
    EXPECT_NEAR(a[1], 0.3 * 4.0 - b * 0.6 / mb, 1e-12);  // r̈ = ω² r − b ṙ / m (Lagrange)
    EXPECT_NEAR(l[1] - a[1], -b * 0.6 / mb, 1e-12);
    EXPECT_NEAR(l[0], a[0], 1e-12);
  }
  {  // LuGre on the bead: also velocity dependent.
    ForceSet lugre;
    lugre.add(std::make_shared<LuGreFriction>(model, "bead", LuGreParams{}));
    const Eigen::VectorXd a = qdd_with(lugre, false), l = qdd_with(lugre, true);
    EXPECT_GT(std::abs(l[1] - a[1]), 1e-3);
  }
  {  // Springs and prescribed efforts only: identical.
    ForceSet plain;
    plain.add(joint_spring(model, "bead", 5.0, 0.1));
    plain.add(joint_effort(model, "bead", constant(0.3)));
    plain.add(joint_effort(model, "spin", constant(-0.2)));
    const Eigen::VectorXd a = qdd_with(plain, false), l = qdd_with(plain, true);
    EXPECT_TRUE(near(a, l, 0, 0));
  }
}

// ================================================================ (g) make_consistent

TEST(MakeConsistent, NewtonProjectionReachesTheConstraintsAndReportsTheCorrection) {
  models::PaperExample ex;
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  std::mt19937 rng(47);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = ex.q0() + test::random_vector(rng, 3, 0.02);
    const Eigen::VectorXd qd = test::random_vector(rng, 3, 0.1);
    const double t = 0.5 * trial;
    auto c = rd.make_consistent(t, q, qd);
    EXPECT_TRUE(c.converged) << trial;
    EXPECT_GT(c.residual_before, 1e-3);
    EXPECT_LT(c.residual_after, 1e-12);
    EXPECT_GE(c.iterations, 2);
    EXPECT_TRUE(near(c.dq, c.q - q, 0, 0));
    EXPECT_TRUE(near(c.dqd, c.qd - qd, 0, 0));
    EXPECT_EQ(c.dq[0], 0.0);  // ψ1 is independent: untouched
    EXPECT_EQ(c.dqd[0], 0.0);
    EXPECT_GT(c.dq.norm(), 1e-3);
    // Independent evaluation.
    Residuals phi(ex.model, ex.constraints);
    Eigen::VectorXd x(6);
    x << c.q, c.qd;
    EXPECT_LT(phi(t, x).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT(phi.ev.phid.cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(rd.residual(t, rd.make_state(c.q, c.qd)), phi(t, x).cwiseAbs().maxCoeff(), 1e-15);
  }
  // First-order rows: only the velocity is corrected.
  const Model model = build_model(sleigh(2.0, 0.3));
  ConstraintSet set;
  set.add(knife_edge(model, "P", Vec3::UnitY()));
  ForceSet forces;
  ReferenceDynamics rs(model, forces, set);
  Eigen::VectorXd q(3), qd(3);
  q << 0.1, -0.2, 0.7;
  qd << 0.3, 0.4, -0.2;
  auto c = rs.make_consistent(0.0, q, qd);
  EXPECT_TRUE(c.converged);
  EXPECT_EQ(c.dq.norm(), 0.0);
  EXPECT_GT(c.dqd.norm(), 1e-3);
  EXPECT_NEAR(-std::sin(0.7) * c.qd[0] + std::cos(0.7) * c.qd[1], 0.0, 1e-14);
}

// ================================================================ misc

TEST(ReferenceDynamics, SizesStateAndArgumentChecks) {
  models::PaperExample ex;
  ReferenceDynamics rd(ex.model, ex.forces, ex.constraints, ex.options());
  EXPECT_EQ(rd.nq(), 3);
  EXPECT_EQ(rd.num_constraints(), 2);
  EXPECT_EQ(rd.num_force_states(), 3);
  EXPECT_EQ(rd.state_size(), 9);
  const Eigen::VectorXd x = rd.make_state(ex.q0(), Eigen::VectorXd::Zero(3));
  EXPECT_EQ(x.size(), 9);
  EXPECT_EQ(x.tail(3).norm(), 0.0);
  Eigen::VectorXd xdot(9), small(8);
  expect_error_mentioning([&] { rd.derivative(0.0, small, xdot); }, {"x", "expected size 9", "got size 8"});
  expect_error_mentioning([&] { rd.make_state(Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(3)); }, {"q"});
  Eigen::VectorXd bad = x;
  bad[4] = std::nan("");
  EXPECT_THROW(rd.derivative(0.0, bad, xdot), NumericalFailure);
  // Too many constraint rows.
  const Model model = build_model(planar_arm(2));
  ConstraintSet set;
  set.add(point_coordinate(model, "tip", 0, constant(1.0)));
  set.add(point_coordinate(model, "tip", 1, constant(1.0)));
  set.add(point_coordinate(model, "tip", 2, constant(0.0)));
  ForceSet forces;
  expect_error_mentioning([&] { ReferenceDynamics(model, forces, set); }, {"constraint rows", "got 3"});
  // Options.
  ReferenceDynamicsOptions o;
  o.alpha = -1;
  expect_error_mentioning([&] { o.validate(); }, {"alpha"});
  o = {};
  o.beta = std::nan("");
  expect_error_mentioning([&] { o.validate(); }, {"beta"});
  o = {};
  o.beta_first_order = -2;
  expect_error_mentioning([&] { o.validate(); }, {"beta_first_order"});
  o = {};
  o.max_condition = 0.5;
  expect_error_mentioning([&] { o.validate(); }, {"max_condition"});
}
