// The generic multibody core (refdyn/multibody/) against the rest of refdyn, on random models of
// 1..30 DOF (standard and modified DH chains, trees, revolute and prismatic joints, folded fixed
// links, general and non-unit joint axes):
//  - double: against the fast kernels (RNEA, M by CRBA, c + g, g, poses, point position,
//    Jacobian, velocity and acceleration) — two independent implementations;
//  - Dual<1>, Dual<8>: exact directional derivatives against central differences of the double
//    instantiation (time derivatives along the motion and ∂τ/∂q in eight directions at once);
//  - GiNaC::ex: symbolic q, q̇, q̈ evaluated at numbers against the double instantiation.
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/detail/fold.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"

#include "../src/symbolic/ginac_scalar.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

namespace refdyn {
namespace {

namespace mb = multibody;

struct Case {
  std::string label;
  Model model;
};

/// For each size: a standard-DH chain, a modified-DH chain with fixed links, a tree, and a tree
/// with general joint axes of non-unit length (build_model normalizes them) and fixed links; 30 %
/// of the joints prismatic.
std::vector<Case> random_models(std::mt19937& rng, const std::vector<int>& sizes = {1, 2, 3, 5, 8, 13, 21, 30}) {
  std::normal_distribution<double> nd(0, 1);  // one for the whole family, as the draws were made before
  auto non_unit_axes = [&nd](std::mt19937& r, ModelDescription& d) {
    for (std::size_t i = 0; i < d.links.size(); ++i)
      d.links[i].axis = Vec3(nd(r), nd(r), nd(r)).normalized() * (0.25 + 0.5 * static_cast<double>(i % 5));
  };
  std::vector<Case> out;
  for (auto& c : test::random_model_family(rng, sizes, non_unit_axes, "tree, non-unit general axes +fixed"))
    out.push_back({c.label, build_model(c.desc)});
  return out;
}

std::vector<double> to_std(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }
Eigen::VectorXd to_eigen(const std::vector<double>& v) { return Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()); }
Vec3 to_eigen(const mb::Vec3T<double>& v) { return {v[0], v[1], v[2]}; }
double scale_of(const Eigen::MatrixXd& a) { return std::max(1.0, a.cwiseAbs().maxCoeff()); }

/// Generic double τ = M q̈ + c + g (qd, qdd may be empty: zero).
std::vector<double> generic_tau(const mb::Bodies<double>& B, const Vec3& g, const Eigen::VectorXd& q,
                                const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd, bool gravity) {
  const mb::Poses<double> P = mb::forward_poses(B, to_std(q));
  return mb::inverse_dynamics(B, P, g, qd.size() ? qd.data() : nullptr, qdd.size() ? qdd.data() : nullptr, gravity);
}

TEST(GenericDynamics, DoubleEqualsTheFastKernels) {
  std::mt19937 rng(20);
  int tip_checks = 0;
  for (const Case& c : random_models(rng)) {
    SCOPED_TRACE(c.label);
    const Model& model = c.model;
    const int n = model.nv;
    Data data(model);
    const mb::Bodies<double> B = mb::bodies_from_model<double>(model);
    for (int trial = 0; trial < 3; ++trial) {
      const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                            qdd = test::random_vector(rng, n, 2.0), none;
      const Eigen::VectorXd tau = inverse_dynamics(model, data, q, qd, qdd);
      EXPECT_LE((to_eigen(generic_tau(B, model.gravity, q, qd, qdd, true)) - tau).cwiseAbs().maxCoeff(),
                1e-12 * scale_of(tau));
      const Eigen::VectorXd nle = bias_forces(model, data, q, qd);
      EXPECT_LE((to_eigen(generic_tau(B, model.gravity, q, qd, none, true)) - nle).cwiseAbs().maxCoeff(),
                1e-12 * scale_of(nle));
      const Eigen::VectorXd g = gravity_forces(model, data, q);
      EXPECT_LE((to_eigen(generic_tau(B, model.gravity, q, none, none, true)) - g).cwiseAbs().maxCoeff(),
                1e-12 * scale_of(g));
      const Eigen::MatrixXd M = mass_matrix(model, data, q);
      const mb::Poses<double> P = mb::forward_poses(B, to_std(q));
      const Eigen::MatrixXd Mg =
          Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
              mb::mass_matrix(B, P).data(), n, n);
      EXPECT_LE((Mg - M).cwiseAbs().maxCoeff(), 1e-12 * scale_of(M));
      // the composite-rigid-body algorithm over the same scalar (the generator's M)
      const Eigen::MatrixXd Mc =
          Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
              mb::crba(B, P).data(), n, n);
      EXPECT_LE((Mc - M).cwiseAbs().maxCoeff(), 1e-12 * scale_of(M));

      // poses and point kinematics
      forward_kinematics(model, data, q);
      for (int i = 0; i < n; ++i) {
        Mat3 R;
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) R(r, k) = P.R[i][3 * r + k];
        EXPECT_LE((R - data.oMi[i].R).cwiseAbs().maxCoeff(), 1e-13) << "body " << i;
        EXPECT_LE((to_eigen(P.p[i]) - data.oMi[i].p).cwiseAbs().maxCoeff(), 1e-12) << "body " << i;
      }
      mb::Motions<double> mo;
      mb::forward_motion(B, P, qd.data(), qdd.data(), mb::zero3<double>(), true, mo);
      for (int k = 0; k < static_cast<int>(model.point_name.size()); ++k) {
        const mb::PointKinematics<double> pk = mb::point_kinematics(B.points[k], P, mo);
        const Vec3 r = point_position(model, data, k);
        point_jacobian(model, data, k);
        const Eigen::MatrixXd C = data.Jp;
        const PointDrift dr = point_drift(model, data, k, qd);
        const double s = std::max(1.0, r.norm());
        EXPECT_LE((to_eigen(pk.r) - r).cwiseAbs().maxCoeff(), 1e-12 * s);
        EXPECT_LE((to_eigen(pk.v) - C * qd).cwiseAbs().maxCoeff(), 1e-11 * s);
        const Vec3 a = C * qdd + dr.drift;
        EXPECT_LE((to_eigen(pk.a) - a).cwiseAbs().maxCoeff(), 1e-11 * std::max(1.0, a.norm()));
        Eigen::MatrixXd Cg = Eigen::MatrixXd::Zero(3, n);
        const int b = model.point_body[k];
        if (b >= 0)
          for (int j : model.support[b]) Cg.col(j) = to_eigen(mb::point_jacobian_column(B, P, j, pk.r));
        EXPECT_LE((Cg - C).cwiseAbs().maxCoeff(), 1e-12 * s);
        ++tip_checks;
      }
    }
  }
  EXPECT_GT(tip_checks, 0);
}

/// f(x + h d) − f(x − h d) over 2h, elementwise.
template <class F>
std::vector<double> central(const F& f, double h) {
  const std::vector<double> p = f(h), m = f(-h);
  std::vector<double> r(p.size());
  for (std::size_t k = 0; k < p.size(); ++k) r[k] = (p[k] - m[k]) / (2 * h);
  return r;
}
double rel_err(const std::vector<double>& a, const std::vector<double>& b) {
  double e = 0, s = 1;
  for (std::size_t k = 0; k < a.size(); ++k) {
    e = std::max(e, std::abs(a[k] - b[k]));
    s = std::max(s, std::abs(b[k]));
  }
  return e / s;
}

TEST(GenericDynamics, DualDerivativesEqualCentralDifferences) {
  std::mt19937 rng(21);
  constexpr double h = 1e-6;
  using D1 = mb::Dual<1>;
  using D8 = mb::Dual<8>;
  for (const Case& c : random_models(rng, {1, 2, 5, 13, 30})) {
    SCOPED_TRACE(c.label);
    const Model& model = c.model;
    const int n = model.nv;
    const mb::Bodies<double> B = mb::bodies_from_model<double>(model);
    const Eigen::VectorXd q = test::random_vector(rng, n, 3.0), qd = test::random_vector(rng, n, 2.0),
                          qdd = test::random_vector(rng, n, 2.0);

    // d/dt along the motion (q̇, q̈, q⃛ = 0) of τ and of the tip's acceleration and Jacobian
    const mb::Bodies<D1> B1 = mb::bodies_from_model<D1>(model);
    std::vector<D1> q1(n), qd1(n), qdd1(n);
    for (int i = 0; i < n; ++i) {
      q1[i] = D1::variable(q[i], 0, qd[i]);
      qd1[i] = D1::variable(qd[i], 0, qdd[i]);
      qdd1[i] = D1(qdd[i]);
    }
    const mb::Poses<D1> P1 = mb::forward_poses(B1, q1);
    const std::vector<D1> tau1 = mb::inverse_dynamics(B1, P1, model.gravity, qd1.data(), qdd1.data(), true);
    mb::Motions<D1> mo1;
    mb::forward_motion(B1, P1, qd1.data(), qdd1.data(), mb::zero3<D1>(), true, mo1);
    const int tip = static_cast<int>(model.point_name.size()) - 1;
    const mb::PointKinematics<D1> k1 = mb::point_kinematics(B1.points[tip], P1, mo1);
    std::vector<double> dtau(n), dacc(3);
    for (int i = 0; i < n; ++i) dtau[i] = tau1[i].d[0];
    for (int i = 0; i < 3; ++i) dacc[i] = k1.a[i].d[0];
    auto along = [&](double s) {
      return std::make_pair(Eigen::VectorXd(q + s * qd), Eigen::VectorXd(qd + s * qdd));
    };
    EXPECT_LE(rel_err(dtau, central([&](double s) {
                        const auto [qs, qds] = along(s);
                        return generic_tau(B, model.gravity, qs, qds, qdd, true);
                      }, h)),
              1e-7);
    EXPECT_LE(rel_err(dacc, central([&](double s) {
                        const auto [qs, qds] = along(s);
                        const mb::Poses<double> P = mb::forward_poses(B, to_std(qs));
                        mb::Motions<double> mo;
                        mb::forward_motion(B, P, qds.data(), qdd.data(), mb::zero3<double>(), true, mo);
                        const mb::Vec3T<double> a = mb::point_kinematics(B.points[tip], P, mo).a;
                        return std::vector<double>(a.begin(), a.end());
                      }, h)),
              1e-7);

    // ∂τ/∂q along eight random directions at once (a Jacobian block)
    const mb::Bodies<D8> B8 = mb::bodies_from_model<D8>(model);
    Eigen::MatrixXd dirs = Eigen::MatrixXd::Random(n, 8);
    std::vector<D8> q8(n), qd8(n), qdd8(n);
    for (int i = 0; i < n; ++i) {
      q8[i] = D8(q[i]);
      for (int k = 0; k < 8; ++k) q8[i].d[k] = dirs(i, k);
      qd8[i] = D8(qd[i]);
      qdd8[i] = D8(qdd[i]);
    }
    const mb::Poses<D8> P8 = mb::forward_poses(B8, q8);
    const std::vector<D8> tau8 = mb::inverse_dynamics(B8, P8, model.gravity, qd8.data(), qdd8.data(), true);
    for (int k = 0; k < 8; ++k) {
      std::vector<double> dk(n);
      for (int i = 0; i < n; ++i) dk[i] = tau8[i].d[k];
      EXPECT_LE(rel_err(dk, central([&](double s) {
                          return generic_tau(B, model.gravity, q + s * dirs.col(k), qd, qdd, true);
                        }, h)),
                1e-7)
          << "direction " << k;
    }
    // the value part does not depend on the number of directions (up to FMA contraction)
    for (int i = 0; i < n; ++i) EXPECT_NEAR(tau8[i].v, tau1[i].v, 1e-13 * std::max(1.0, std::abs(tau1[i].v)));
  }
}

/// The model fold (multibody/detail/fold.hpp) over the generic pose and inertia algebra (PoseT,
/// transform_inertia; here over Dual<1>, as the generator folds over GiNaC::ex) against
/// build_model's fold over the spatial algebra (SE3, Inertia): placements, inertias, link frames
/// and points (on the world, on the base at a base pose, on every link) on random models with
/// folded fixed links, both DH conventions and trees. Also the DH rows' frames (dh_frames) over
/// both algebras.
TEST(GenericDynamics, FoldOverTheGenericAlgebraEqualsBuildModel) {
  using D = mb::Dual<1>;
  using A = mb::FoldAlgebra<D>;
  std::mt19937 rng(35);
  std::normal_distribution<double> nd(0, 1);
  auto lift_pose = [](const SE3& X) { return A::Pose{mb::lift<D>(X.R), mb::lift<D>(X.p)}; };
  auto value = [](const D& x) { return x.v; };
  auto near = [&](const mb::Mat3T<D>& a, const Mat3& b) {
    double e = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) e = std::max(e, std::abs(value(a[3 * i + j]) - b(i, j)));
    return e;
  };
  auto near3 = [&](const mb::Vec3T<D>& a, const Vec3& b) {
    return std::max({std::abs(value(a[0]) - b[0]), std::abs(value(a[1]) - b[1]), std::abs(value(a[2]) - b[2])});
  };
  auto no_axes = [](std::mt19937&, ModelDescription&) {};
  int cases = 0;
  for (auto& c : test::random_model_family(rng, {1, 3, 8, 21}, no_axes, "tree +fixed")) {
    SCOPED_TRACE(c.label);
    ModelDescription d = c.desc;
    d.base = SE3::rot_z(nd(rng)) * SE3::rot_x(nd(rng)) * SE3::trans(Vec3(nd(rng), nd(rng), nd(rng)));
    d.points.clear();
    d.add_point("on_world", "world", Vec3(nd(rng), nd(rng), nd(rng)));
    d.add_point("on_base", "base", Vec3(nd(rng), nd(rng), nd(rng)));
    for (const LinkSpec& l : c.desc.links) d.add_point("on_" + l.name, l.name, Vec3(nd(rng), nd(rng), nd(rng)));
    const Model model = build_model(d);
    std::vector<mb::FoldLink<D>> links;
    for (const LinkSpec& l : d.links) {
      const auto m = mb::from_double<D>(l.inertia.mass);
      links.push_back({l.parent, l.type, lift_pose(l.placement), lift_pose(l.link_offset),
                       A::from_com(m, mb::lift<D>(l.inertia.com), mb::lift<D>(l.inertia.I_com))});
    }
    const mb::Folded<D> f = mb::fold_links(links, lift_pose(d.base));
    ASSERT_EQ(f.size(), model.nv);
    constexpr double tol = 1e-12;
    for (int b = 0; b < model.nv; ++b) {
      EXPECT_EQ(f.parent[b], model.parent[b]);
      EXPECT_LE(near(f.placement[b].R, model.placement[b].R), tol);
      EXPECT_LE(near3(f.placement[b].p, model.placement[b].p), tol);
      const Inertia& I = model.inertia[b];
      EXPECT_LE(std::abs(value(f.inertia[b].m) - I.m), tol * (1 + I.m));
      EXPECT_LE(near3(f.inertia[b].h, I.h), tol * (1 + I.h.norm()));
      EXPECT_LE(near(f.inertia[b].I, I.I), tol * (1 + I.I.norm()));
    }
    for (std::size_t i = 0; i < d.links.size(); ++i) {
      EXPECT_EQ(f.body_of[i], model.frame_body[i]);
      EXPECT_LE(near(f.link_in_body[i].R, model.frame_pose[i].R), tol);
      EXPECT_LE(near3(f.link_in_body[i].p, model.frame_pose[i].p), tol);
    }
    for (std::size_t k = 0; k < d.points.size(); ++k) {
      const PointSpec& p = d.points[k];
      const int link = k == 0 ? mb::kOnWorld : k == 1 ? mb::kOnBase : static_cast<int>(k) - 2;  // as added above
      const mb::FoldedPoint<D> fp = mb::place_point(f, link, lift_pose(d.base), mb::lift<D>(p.position));
      const int pk = model.point_index(p.name);
      EXPECT_EQ(fp.body, model.point_body[pk]);
      EXPECT_LE(near3(fp.position, model.point_position[pk]), tol * (1 + p.position.norm()));
    }
    ++cases;
  }
  EXPECT_EQ(cases, 16);
  // the DH frames of a row, over both algebras
  for (JointType type : {JointType::Revolute, JointType::Prismatic, JointType::Fixed})
    for (bool standard : {true, false}) {
      const double th = nd(rng), dd = nd(rng), a = nd(rng), al = nd(rng);
      const mb::DHFrames<double> x = mb::dh_frames(type, th, dd, a, al, standard);
      const mb::DHFrames<D> y = mb::dh_frames(type, mb::from_double<D>(th), mb::from_double<D>(dd),
                                              mb::from_double<D>(a), mb::from_double<D>(al), standard);
      EXPECT_LE(near(y.placement.R, x.placement.R), 1e-15);
      EXPECT_LE(near3(y.placement.p, x.placement.p), 1e-15);
      EXPECT_LE(near(y.link_offset.R, x.link_offset.R), 1e-15);
      EXPECT_LE(near3(y.link_offset.p, x.link_offset.p), 1e-15);
      EXPECT_EQ(value(y.offset), x.offset);
    }
}

TEST(GenericDynamics, DualArithmeticIsTheChainRule) {
  using D2 = mb::Dual<2>;
  const D2 x = D2::variable(0.7, 0), y = D2::variable(1.9, 1);  // ∂/∂x, ∂/∂y
  const D2 f = mb::sin(x) * y / (mb::sqrt(y) + 2.0) - mb::cos(x * y) + 3.0 * x - (-y);
  const double sx = std::sin(0.7), sy = std::sqrt(1.9), den = sy + 2.0;
  const double fx = std::cos(0.7) * 1.9 / den + std::sin(0.7 * 1.9) * 1.9 + 3.0;
  const double fy = sx / den - sx * 1.9 * (0.5 / sy) / (den * den) + std::sin(0.7 * 1.9) * 0.7 + 1.0;
  EXPECT_NEAR(f.v, sx * 1.9 / den - std::cos(0.7 * 1.9) + 2.1 + 1.9, 1e-14);  // |f| ≈ 4: a few ulp
  EXPECT_NEAR(f.d[0], fx, 1e-14);
  EXPECT_NEAR(f.d[1], fy, 1e-14);
  EXPECT_TRUE(mb::is_zero(mb::from_double<D2>(0.0)));
  EXPECT_FALSE(mb::is_zero(D2::variable(0.0, 1)));  // zero value, nonzero derivative
}

double eval(const GiNaC::ex& e, const GiNaC::exmap& at) {
  const GiNaC::ex v = e.subs(at, GiNaC::subs_options::no_pattern).evalf();
  EXPECT_TRUE(GiNaC::is_a<GiNaC::numeric>(v)) << v;
  return GiNaC::ex_to<GiNaC::numeric>(v).to_double();
}

TEST(GenericDynamics, GinacEvaluatesToTheDoubleInstantiation) {
  std::mt19937 rng(22);
  using GiNaC::ex;
  for (const Case& c : random_models(rng, {1, 2, 3, 4})) {
    SCOPED_TRACE(c.label);
    const Model& model = c.model;
    const int n = model.nv;
    const mb::Bodies<double> B = mb::bodies_from_model<double>(model);
    const mb::Bodies<ex> Bs = mb::bodies_from_model<ex>(model);
    std::vector<ex> q, qd, qdd;
    GiNaC::exmap at;
    const Eigen::VectorXd qv = test::random_vector(rng, n, 3.0), qdv = test::random_vector(rng, n, 2.0),
                          qddv = test::random_vector(rng, n, 2.0);
    for (int i = 0; i < n; ++i) {
      const GiNaC::realsymbol a("q" + std::to_string(i)), b("qd" + std::to_string(i)), d("qdd" + std::to_string(i));
      q.push_back(a);
      qd.push_back(b);
      qdd.push_back(d);
      at[a] = qv[i];
      at[b] = qdv[i];
      at[d] = qddv[i];
    }
    const mb::Poses<ex> Ps = mb::forward_poses(Bs, q);
    const std::vector<ex> tau = mb::inverse_dynamics(Bs, Ps, model.gravity, qd.data(), qdd.data(), true);
    const std::vector<double> tau_d = generic_tau(B, model.gravity, qv, qdv, qddv, true);
    std::vector<double> tau_s(n);
    for (int i = 0; i < n; ++i) tau_s[i] = eval(tau[i], at);
    EXPECT_LE(rel_err(tau_s, tau_d), 1e-12);
    const std::vector<ex> M = mb::mass_matrix(Bs, Ps);
    const mb::Poses<double> P = mb::forward_poses(B, to_std(qv));
    const std::vector<double> Md = mb::mass_matrix(B, P);
    std::vector<double> Ms(M.size());
    for (std::size_t k = 0; k < M.size(); ++k) Ms[k] = eval(M[k], at);
    EXPECT_LE(rel_err(Ms, Md), 1e-12);
    const int tip = static_cast<int>(model.point_name.size()) - 1;
    const mb::Vec3T<ex> r = mb::point_position(Bs.points[tip], Ps);
    const mb::Vec3T<double> rd = mb::point_position(B.points[tip], P);
    EXPECT_LE(rel_err({eval(r[0], at), eval(r[1], at), eval(r[2], at)}, {rd[0], rd[1], rd[2]}), 1e-12);
  }
}

/// Larger models with GiNaC numbers for q, q̇, q̈ (every operation evaluates at once, in CLN's
/// double floats): the GiNaC instantiation of the whole recursion at 13 and 30 DOF.
TEST(GenericDynamics, GinacWithNumbersEqualsTheDoubleInstantiation) {
  std::mt19937 rng(23);
  using GiNaC::ex;
  for (const Case& c : random_models(rng, {13, 30})) {
    SCOPED_TRACE(c.label);
    const Model& model = c.model;
    const int n = model.nv;
    const mb::Bodies<double> B = mb::bodies_from_model<double>(model);
    const mb::Bodies<ex> Bs = mb::bodies_from_model<ex>(model);
    const Eigen::VectorXd qv = test::random_vector(rng, n, 3.0), qdv = test::random_vector(rng, n, 2.0),
                          qddv = test::random_vector(rng, n, 2.0);
    std::vector<ex> q, qd, qdd;
    // The state as floating-point numbers (GiNaC evaluates sin/cos of a float; from_double<ex>
    // gives exact rationals, whose sines stay symbolic and whose products grow without bound).
    for (int i = 0; i < n; ++i) {
      q.push_back(GiNaC::numeric(qv[i]));
      qd.push_back(GiNaC::numeric(qdv[i]));
      qdd.push_back(GiNaC::numeric(qddv[i]));
    }
    const mb::Poses<ex> Ps = mb::forward_poses(Bs, q);
    const std::vector<ex> tau = mb::inverse_dynamics(Bs, Ps, model.gravity, qd.data(), qdd.data(), true);
    std::vector<double> tau_s(n);
    const GiNaC::exmap none;
    for (int i = 0; i < n; ++i) tau_s[i] = eval(tau[i], none);
    EXPECT_LE(rel_err(tau_s, generic_tau(B, model.gravity, qv, qdv, qddv, true)), 1e-12);
  }
}

}  // namespace
}  // namespace refdyn
