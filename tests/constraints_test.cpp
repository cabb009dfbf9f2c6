// Constraints: for every ready-made kind, on random chains (standard/modified DH, chains/trees,
// with/without fixed links) at random states,
//   holonomic rows:    A = ∂Φ/∂q, Φ̇ = dΦ/dt along (q̇, t), Φ̈ = A q̈ + γ,
//   first-order rows:  A = ∂c/∂q̇, ċ = A q̈ + γ,
// all by central finite differences along the motion q(s) = q + q̇ s + ½ q̈ s²,
// q̇(s) = q̇ + q̈ s, t(s) = t + s (whose derivative at s = 0 is exactly the total derivative
// with acceleration q̈). Also ConstraintSet bookkeeping and argument validation.
//
// FD budget (central, step h = 1e-5; |Φ| and lever arms of a few metres, |q̇|, |q̈| ≤ 2):
// truncation h²|f'''|/6 ≲ 1e-10·|f'''| with |f'''| ≲ 1e2 along the path, rounding ε|f|/h ≲ 1e-10.
// The tolerance 1e-7 (relative to the row's scale, with an absolute floor of 1e-7) keeps a
// factor ~100 above both.
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "test_support.hpp"

#include <cmath>
#include <numbers>

using namespace refdyn;
using refdyn::test::near;

namespace {

constexpr double kH = 1e-5;
constexpr double kTol = 1e-7;

using Case = test::RandomModelCase;
using test::model_zoo;

using test::all_kinds;
using test::random_unit;
using test::renamed;

struct Eval {
  Eigen::VectorXd phi, phid, gamma;
  Eigen::MatrixXd A;
};

Eval eval(const Model& model, const ConstraintSet& set, double t, const Eigen::VectorXd& q,
          const Eigen::VectorXd& qd) {
  Data data(model);
  ConstraintEval ev(model, set);
  evaluate_constraints(model, data, set, ev, t, q, qd);
  return {ev.phi, ev.phid, ev.gamma, ev.A};
}

}  // namespace

TEST(Constraints, JacobianVelocityAndDriftMatchFiniteDifferences) {
  std::mt19937 rng(31);
  int rows_checked = 0, first_order_rows = 0;
  double worst_A = 0, worst_phid = 0, worst_gamma = 0;
  for (int dof : {4, 7}) {
    for (const Case& c : model_zoo(rng, dof)) {
      const Model model = build_model(c.desc);
      const int n = model.nq;
      const ConstraintSet set = all_kinds(model, rng);
      ASSERT_EQ(set.rows(), 16);
      for (int trial = 0; trial < 4; ++trial) {
        const Eigen::VectorXd q = test::random_vector(rng, n, 3.0);
        const Eigen::VectorXd qd = test::random_vector(rng, n, 2.0);
        const Eigen::VectorXd qdd = test::random_vector(rng, n, 2.0);
        const double t = std::uniform_real_distribution<double>(0.0, 3.0)(rng);
        const Eval e = eval(model, set, t, q, qd);
        ASSERT_TRUE(e.phi.allFinite() && e.phid.allFinite() && e.gamma.allFinite() && e.A.allFinite());

        // ∂/∂q (holonomic) and ∂/∂q̇ (first order), column by column.
        Eigen::MatrixXd dq(set.rows(), n), dqd(set.rows(), n);
        for (int j = 0; j < n; ++j) {
          Eigen::VectorXd qp = q, qm = q, vp = qd, vm = qd;
          qp[j] += kH;
          qm[j] -= kH;
          vp[j] += kH;
          vm[j] -= kH;
          dq.col(j) = (eval(model, set, t, qp, qd).phi - eval(model, set, t, qm, qd).phi) / (2 * kH);
          dqd.col(j) = (eval(model, set, t, q, vp).phi - eval(model, set, t, q, vm).phi) / (2 * kH);
        }
        // Along the motion.
        auto at = [&](double s) {
          return eval(model, set, t + s, q + qd * s + 0.5 * qdd * s * s, qd + qdd * s);
        };
        const Eval ep = at(kH), em = at(-kH);
        const Eigen::VectorXd dphi = (ep.phi - em.phi) / (2 * kH);    // Φ̇ (hol.) or ċ (1st order)
        const Eigen::VectorXd dphid = (ep.phid - em.phid) / (2 * kH);  // Φ̈ (hol.)
        // Φ̇ along (q̇, t) alone, without q̈ (the q̈ term is O(s²) in Φ, so it does not matter
        // for the first derivative; checked separately to be explicit).
        const Eigen::VectorXd dphi_v =
            (eval(model, set, t + kH, q + qd * kH, qd).phi - eval(model, set, t - kH, q - qd * kH, qd).phi) /
            (2 * kH);
        const Eigen::VectorXd predicted = e.A * qdd + e.gamma;

        for (int r = 0; r < set.rows(); ++r) {
          const std::string where = c.label + ", row " + set.row_name(r) + ", trial " + std::to_string(trial);
          const bool fo = set.row_first_order(r);
          if (fo) {
            ++first_order_rows;
            EXPECT_TRUE(near(e.A.row(r), dqd.row(r), kTol, kTol)) << where << " (A = ∂c/∂q̇)";
            EXPECT_EQ(e.phid[r], e.phi[r]) << where;
            EXPECT_TRUE(near(Eigen::VectorXd::Constant(1, predicted[r]), Eigen::VectorXd::Constant(1, dphi[r]), kTol,
                             kTol))
                << where << " (ċ = A q̈ + γ)";
            worst_A = std::max(worst_A, test::rel_diff(e.A.row(r), dqd.row(r), 1.0));
            worst_gamma = std::max(worst_gamma, std::abs(predicted[r] - dphi[r]) / std::max(1.0, std::abs(dphi[r])));
          } else {
            EXPECT_TRUE(near(e.A.row(r), dq.row(r), kTol, kTol)) << where << " (A = ∂Φ/∂q)";
            EXPECT_NEAR(e.phid[r], dphi_v[r], kTol * std::max(1.0, std::abs(dphi_v[r]))) << where << " (Φ̇)";
            EXPECT_NEAR(e.phid[r], dphi[r], kTol * std::max(1.0, std::abs(dphi[r]))) << where << " (Φ̇, path)";
            EXPECT_NEAR(predicted[r], dphid[r], kTol * std::max(1.0, std::abs(dphid[r])))
                << where << " (Φ̈ = A q̈ + γ)";
            // The first-order part of the identity: Φ̇ = A q̇ + Φ_t, i.e. A q̇ is the
            // velocity-dependent part (Φ_t from the difference along t alone).
            const double phit =
                (eval(model, set, t + kH, q, qd).phi[r] - eval(model, set, t - kH, q, qd).phi[r]) / (2 * kH);
            EXPECT_NEAR(e.phid[r], e.A.row(r).dot(qd) + phit, kTol * std::max(1.0, std::abs(e.phid[r]))) << where;
            worst_A = std::max(worst_A, test::rel_diff(e.A.row(r), dq.row(r), 1.0));
            worst_phid = std::max(worst_phid, std::abs(e.phid[r] - dphi[r]) / std::max(1.0, std::abs(dphi[r])));
            worst_gamma =
                std::max(worst_gamma, std::abs(predicted[r] - dphid[r]) / std::max(1.0, std::abs(dphid[r])));
          }
          ++rows_checked;
        }
      }
    }
  }
  EXPECT_EQ(rows_checked, 2 * 8 * 4 * 16);
  EXPECT_EQ(first_order_rows, 2 * 8 * 4 * 4);
  std::cout << "[ constraints ] worst relative FD mismatch: A " << worst_A << ", phid " << worst_phid << ", gamma "
            << worst_gamma << " over " << rows_checked << " rows\n";
}

TEST(Constraints, ValuesMatchTheReferenceKinematics) {
  std::mt19937 rng(32);
  for (const Case& c : model_zoo(rng, 6)) {
    const Model model = build_model(c.desc);
    const int n = model.nq;
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0);
    const Eigen::VectorXd qd = test::random_vector(rng, n, 2.0);
    const double t = 0.77;
    ASSERT_GE(n, 3);
    const Vec3 tip = test::reference_point_position(c.desc, q, "tip");
    const Vec3 mid = test::reference_point_position(c.desc, q, "mid");
    const Vec3 anchor(0.4, -0.3, 0.8);
    const Vec3 nrm = Vec3(1, -2, 0.5).normalized();
    auto h = sinusoid(0.3, 2.0, 0.1, 0.2);
    auto fx = sinusoid(0.2, 1.7, 0.3, 0.5);
    auto qj = polynomial({0.2, -0.4, 0.3});
    const Vec3 lateral = Vec3(0.3, 0.2, -1.0);
    const Vec3 u = Vec3(-0.5, 0.1, 0.4);
    ConstraintSet set;
    set.add(renamed(point_on_surface(model, "tip", elliptic_cylinder(0.7, 0.4, 0.1, -0.2)), "ellipse"));
    set.add(renamed(point_on_surface(model, "mid", sphere(Vec3(0.2, 0.1, -0.3), 0.8)), "sphere"));
    set.add(renamed(point_on_surface(model, "tip", plane(nrm * 3.0, h)), "plane"));
    set.add(point_coordinate(model, "tip", 0, fx));
    set.add(joint_trajectory(model, model.joint_name[1], qj));
    set.add(points_coincide(model, "mid", "anchor", {2, 0}));
    set.add(knife_edge(model, "tip", lateral));
    set.add(point_speed(model, "tip", u, constant(0.25)));
    set.add(joint_coupling(model, model.joint_name[2], model.joint_name[0], 2.5, -0.4));
    Data data(model);
    ConstraintEval ev(model, set);
    evaluate_constraints(model, data, set, ev, t, q, qd);
    const int tip_index = model.point_index("tip");
    const PointState& P = ev.points[tip_index];
    EXPECT_TRUE(near(P.r, tip, 1e-12, 1e-12)) << c.label;
    EXPECT_TRUE(near(P.v, P.C * qd, 1e-12, 1e-12)) << c.label;
    EXPECT_TRUE(near(P.w, P.Jw * qd, 1e-12, 1e-12)) << c.label;
    const PointState& W = ev.points[model.point_index("anchor")];
    EXPECT_TRUE(near(W.r, anchor, 0, 0));
    EXPECT_EQ(W.C.cwiseAbs().sum(), 0.0);
    EXPECT_EQ(W.v.norm(), 0.0);

    Eigen::VectorXd expected(set.rows());
    expected[0] = std::pow((tip.x() - 0.1) / 0.7, 2) + std::pow((tip.y() + 0.2) / 0.4, 2) - 1;
    expected[1] = (mid - Vec3(0.2, 0.1, -0.3)).squaredNorm() - 0.64;
    expected[2] = nrm.dot(tip) - h->eval(t).f;
    expected[3] = tip.x() - fx->eval(t).f;
    expected[4] = q[1] - qj->eval(t).f;
    expected[5] = mid.z() - anchor.z();
    expected[6] = mid.x() - anchor.x();
    expected[7] = (P.R * lateral.normalized()).dot(P.v);
    expected[8] = u.normalized().dot(P.v) - 0.25;
    expected[9] = q[2] - 2.5 * q[0] + 0.4;
    EXPECT_TRUE(near(ev.phi, expected, 1e-12, 1e-12)) << c.label;
    // Lateral axis in the body: R from the reference poses.
    const std::vector<SE3> T = test::reference_link_poses(c.desc, q);
    const int link = [&] {
      for (size_t i = 0; i < c.desc.links.size(); ++i)
        if (c.desc.links[i].name == c.desc.points[0].link) return static_cast<int>(i);
      return -1;
    }();
    ASSERT_GE(link, 0);
    // The tip's body frame and the link frame differ by a fixed rotation (link offset / fixed
    // links); the knife edge uses the body frame. Check R against the reference up to that.
    const Mat3 fixed = T[static_cast<size_t>(link)].R.transpose() * P.R;
    Eigen::VectorXd q2 = test::random_vector(rng, n, 3.0);
    evaluate_constraints(model, data, set, ev, t, q2, qd);
    const std::vector<SE3> T2 = test::reference_link_poses(c.desc, q2);
    EXPECT_TRUE(near(T2[static_cast<size_t>(link)].R.transpose() * ev.points[tip_index].R, fixed, 1e-12, 1e-12))
        << c.label;
  }
}

// The reference dynamics evaluates the constraints right after CRBA + RNEA and takes the body
// velocities and accelerations RNEA left (minus the propagated gravity) instead of a second
// velocity recursion: the two routes must give the same rows and point states, on chains and
// trees, with a rotated base and a gravity vector in a random direction.
TEST(Constraints, AfterBiasForcesEqualsTheStandaloneEvaluation) {
  std::mt19937 rng(36);
  for (Case& c : model_zoo(rng, 5)) {
    c.desc.gravity = 9.81 * random_unit(rng);
    c.desc.base = SE3{Eigen::AngleAxisd(0.7, random_unit(rng)).toRotationMatrix(), test::random_vector(rng, 3)};
    const Model model = build_model(c.desc);
    const ConstraintSet set = all_kinds(model, rng);
    for (int trial = 0; trial < 3; ++trial) {
      const Eigen::VectorXd q = test::random_vector(rng, model.nq, 3.0);
      const Eigen::VectorXd qd = test::random_vector(rng, model.nq, 2.0);
      const double t = 0.3 + trial;
      Data d1(model), d2(model);
      ConstraintEval e1(model, set), e2(model, set);
      evaluate_constraints(model, d1, set, e1, t, q, qd);
      unchecked::crba(model, d2, q);
      unchecked::rnea_reusing_placements(model, d2, q, &qd, nullptr, true, d2.nle);
      evaluate_constraints_after_bias_forces(model, d2, set, e2, t, q, qd);
      EXPECT_TRUE(near(e2.phi, e1.phi, 1e-12, 1e-12)) << c.label;
      EXPECT_TRUE(near(e2.phid, e1.phid, 1e-12, 1e-12)) << c.label;
      EXPECT_TRUE(near(e2.A, e1.A, 1e-12, 1e-12)) << c.label;
      EXPECT_TRUE(near(e2.gamma, e1.gamma, 1e-12, 1e-12)) << c.label;
      for (int k : set.points()) {
        EXPECT_TRUE(near(e2.points[k].d, e1.points[k].d, 1e-12, 1e-12)) << c.label << " point " << k;
        EXPECT_TRUE(near(e2.points[k].wd, e1.points[k].wd, 1e-12, 1e-12)) << c.label << " point " << k;
      }
      // Gravity is really in RNEA's accelerations (else the subtraction above would be untested).
      const int b = model.point_body[set.points().back()] >= 0 ? model.point_body[set.points().back()] : 0;
      EXPECT_GT((d2.a[b].v - d1.a[b].v).norm(), 1.0) << c.label;
    }
  }
}

TEST(ConstraintSet, RowBookkeeping) {
  std::mt19937 rng(33);
  ModelDescription d = test::random_chain(rng, {});
  d.add_point("mid", d.links[2].name, Vec3(0.1, 0.2, 0.3));
  d.add_point("anchor", "world", Vec3(1, 2, 3));
  const Model model = build_model(d);
  ConstraintSet set;
  EXPECT_EQ(set.rows(), 0);
  EXPECT_EQ(set.size(), 0);
  auto ell = point_on_surface(model, "tip", elliptic_cylinder(0.5, 0.25));
  auto coin = points_coincide(model, "tip", "mid");
  auto ke = knife_edge(model, "mid", Vec3(0, 1, 0));
  auto coin2 = points_coincide(model, "mid", "anchor", {0, 1});
  auto sp = point_speed(model, "tip", Vec3(1, 0, 0), constant(0.1));
  auto jt = joint_trajectory(model, "q3", constant(0.2));
  auto pc = point_coordinate(model, "anchor", 2, constant(3.0));
  for (auto c : {ell, coin, ke, coin2, sp, jt, pc}) set.add(c);
  EXPECT_EQ(set.size(), 7);
  EXPECT_EQ(set.rows(), 1 + 3 + 1 + 2 + 1 + 1 + 1);
  const std::vector<int> offsets{0, 1, 4, 5, 7, 8, 9};
  for (int k = 0; k < 7; ++k) EXPECT_EQ(set.row_offset(k), offsets[k]);
  const std::vector<int> owner{0, 1, 1, 1, 2, 3, 3, 4, 5, 6};
  const std::vector<std::string> names{"tip_on_surface", "tip_at_mid[0]", "tip_at_mid[1]", "tip_at_mid[2]",
                                       "no_slip_mid",    "mid_at_anchor[0]", "mid_at_anchor[1]", "speed_tip",
                                       "q_q3",           "z_anchor"};
  const std::vector<bool> fo{false, false, false, false, true, false, false, true, false, false};
  for (int r = 0; r < set.rows(); ++r) {
    EXPECT_EQ(set.row_owner(r), owner[r]) << r;
    EXPECT_EQ(set.row_name(r), names[r]) << r;
    EXPECT_EQ(set.row_first_order(r), fo[r]) << r;
  }
  // Union of points, each once, in first-use order.
  const std::vector<int> pts{model.point_index("tip"), model.point_index("mid"), model.point_index("anchor")};
  EXPECT_EQ(set.points(), pts);
  // Flags and origins.
  EXPECT_EQ(ell->origin, ConstraintOrigin::Programmed);
  EXPECT_EQ(coin->origin, ConstraintOrigin::Material);
  EXPECT_EQ(ke->origin, ConstraintOrigin::Material);
  EXPECT_EQ(sp->origin, ConstraintOrigin::Programmed);
  EXPECT_STREQ(to_string(ConstraintOrigin::Material), "material");
  EXPECT_STREQ(to_string(ConstraintOrigin::Programmed), "programmed");
  EXPECT_FALSE(ell->rheonomic());
  EXPECT_TRUE(point_on_surface(model, "tip", plane(Vec3(0, 0, 1), constant(0)))->rheonomic());
  EXPECT_FALSE(coin->rheonomic());
  EXPECT_TRUE(jt->rheonomic());
  EXPECT_TRUE(sp->first_order());
  EXPECT_TRUE(sp->rheonomic());
  EXPECT_FALSE(ke->rheonomic());
  EXPECT_EQ(jt->points().size(), 0u);
  for (auto c : set.constraints()) EXPECT_FALSE(c->describe().empty()) << c->name;
  EXPECT_EQ(point_on_surface(model, "tip", sphere(Vec3::Zero(), 1.0), ConstraintOrigin::Material)->origin,
            ConstraintOrigin::Material);
}

TEST(ConstraintSet, RejectsDuplicatesUnknownNamesAndBadArguments) {
  std::mt19937 rng(34);
  ModelDescription d = test::random_chain(rng, {});
  d.add_point("mid", d.links[2].name, Vec3(0.1, 0.2, 0.3));
  const Model model = build_model(d);
  auto expect_error = [](auto&& fn, const std::vector<std::string>& needles) {
    try {
      fn();
    } catch (const Error& e) {
      const std::string what = e.what();
      for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
      return;
    }
    ADD_FAILURE() << "expected refdyn::Error mentioning " << needles.front();
  };
  ConstraintSet set;
  set.add(point_on_surface(model, "tip", sphere(Vec3::Zero(), 1.0)));
  expect_error([&] { set.add(point_on_surface(model, "tip", elliptic_cylinder(1, 2))); },
               {"tip_on_surface", "twice"});
  EXPECT_EQ(set.size(), 1);  // the rejected one was not added
  EXPECT_EQ(set.rows(), 1);
  expect_error([&] { set.add(nullptr); }, {"constraint"});
  expect_error([&] { point_on_surface(model, "tpi", sphere(Vec3::Zero(), 1.0)); },
               {"unknown point 'tpi'", "did you mean 'tip'"});
  expect_error([&] { point_coordinate(model, "mdi", 0, constant(0)); }, {"mdi", "did you mean 'mid'"});
  expect_error([&] { points_coincide(model, "tip", "mdi"); }, {"did you mean 'mid'"});
  expect_error([&] { knife_edge(model, "tips", Vec3(0, 1, 0)); }, {"did you mean 'tip'"});
  expect_error([&] { point_speed(model, "tp", Vec3(0, 1, 0), constant(0)); }, {"did you mean 'tip'"});
  expect_error([&] { joint_trajectory(model, "qq3", constant(0)); }, {"unknown joint 'qq3'", "did you mean"});
  expect_error([&] { point_coordinate(model, "tip", 3, constant(0)); }, {"axis", "got 3"});
  expect_error([&] { point_coordinate(model, "tip", 0, nullptr); }, {"time function"});
  expect_error([&] { points_coincide(model, "tip", "tip"); }, {"same"});
  expect_error([&] { points_coincide(model, "tip", "mid", {}); }, {"axis"});
  expect_error([&] { points_coincide(model, "tip", "mid", {0, -1}); }, {"axis"});
  expect_error([&] { knife_edge(model, "tip", Vec3::Zero()); }, {"lateral axis"});
  expect_error([&] { point_speed(model, "tip", Vec3(0, 0, 0), constant(0)); }, {"direction"});
  expect_error([&] { point_speed(model, "tip", Vec3(0, 0, 1), nullptr); }, {"speed function"});
  expect_error([&] { point_on_surface(model, "tip", nullptr); }, {"surface"});
  expect_error([&] { elliptic_cylinder(0.0, 1.0); }, {"half-axes"});
  expect_error([&] { elliptic_cylinder(1.0, -1.0); }, {"half-axes"});
  expect_error([&] { sphere(Vec3::Zero(), 0.0); }, {"sphere"});
  expect_error([&] { plane(Vec3::Zero(), constant(0)); }, {"normal"});
  expect_error([&] { plane(Vec3(0, 0, 1), nullptr); }, {"offset"});
}

TEST(Surfaces, DerivativesMatchFiniteDifferences) {
  std::mt19937 rng(35);
  const std::vector<SurfacePtr> surfaces{elliptic_cylinder(0.7, 0.4, 0.1, -0.2), sphere(Vec3(0.2, 0.1, -0.3), 0.8),
                                         plane(Vec3(1, -2, 0.5), sinusoid(0.3, 2.0, 0.1, 0.2))};
  for (const auto& s : surfaces) {
    for (int k = 0; k < 10; ++k) {
      const Vec3 r = test::random_vector(rng, 3, 2.0);
      const double t = 0.3 * k;
      const auto v = s->eval(r, t);
      Eigen::Vector3d g;
      Mat3 H;
      for (int j = 0; j < 3; ++j) {
        Vec3 rp = r, rm = r;
        rp[j] += kH;
        rm[j] -= kH;
        g[j] = (s->eval(rp, t).f - s->eval(rm, t).f) / (2 * kH);
        H.col(j) = (s->eval(rp, t).grad - s->eval(rm, t).grad) / (2 * kH);
      }
      EXPECT_TRUE(near(v.grad, g, kTol, kTol)) << s->describe();
      EXPECT_TRUE(near(v.hess, H, kTol, kTol)) << s->describe();
      const auto tp = s->eval(r, t + kH), tm = s->eval(r, t - kH);
      EXPECT_NEAR(v.ft, (tp.f - tm.f) / (2 * kH), kTol) << s->describe();
      EXPECT_NEAR(v.ftt, (tp.ft - tm.ft) / (2 * kH), kTol) << s->describe();
      EXPECT_TRUE(near(v.grad_t, (tp.grad - tm.grad) / (2 * kH), kTol, kTol)) << s->describe();
    }
  }
}

TEST(Constraints, EvaluateRefusesWorkspacesOfAnotherModelOrSet) {
  std::mt19937 rng(37);
  ModelDescription d = test::random_chain(rng, {.dof = 4});
  d.add_point("tip2", d.links.back().name, Vec3(0.1, 0.2, 0.0));
  const Model model = build_model(d), other = build_model(test::random_chain(rng, {.dof = 2}));
  ConstraintSet set, set2;
  set.add(point_coordinate(model, "tip2", 2, constant(0.3)));
  set2.add(point_coordinate(model, "tip2", 2, constant(0.3)));
  set2.add(point_coordinate(model, "tip2", 0, constant(0.1)));
  Data data(model), data_other(other);
  ConstraintEval ev(model, set), ev2(model, set2);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(4), qd = Eigen::VectorXd::Zero(4);
  test::expect_error_mentioning([&] { evaluate_constraints(model, data_other, set, ev, 0.0, q, qd); },
                                {"another model"});
  test::expect_error_mentioning([&] { evaluate_constraints(model, data, set, ev2, 0.0, q, qd); },
                                {"ConstraintEval", "same model and set"});
  test::expect_error_mentioning([&] { evaluate_constraints(model, data, set, ev, 0.0, Eigen::VectorXd::Zero(3), qd); },
                                {"q"});
  test::expect_error_mentioning([&] { evaluate_constraints(model, data, set, ev, 0.0, q, Eigen::VectorXd::Zero(5)); },
                                {"qd"});
  EXPECT_NO_THROW(evaluate_constraints(model, data, set, ev, 0.0, q, qd));
}
