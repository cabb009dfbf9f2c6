#include <fstream>
#include <sstream>
#include "test_support.hpp"
#include "test_paths.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>

namespace refdyn::test {

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}


::testing::AssertionResult near(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double rel_tol,
                                double abs_tol) {
  if (a.rows() != b.rows() || a.cols() != b.cols())
    return ::testing::AssertionFailure() << "shape mismatch " << a.rows() << "x" << a.cols() << " vs "
                                         << b.rows() << "x" << b.cols();
  const double scale = std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff());
  double worst = 0;
  Eigen::Index wi = 0, wj = 0;
  for (Eigen::Index j = 0; j < a.cols(); ++j)
    for (Eigen::Index i = 0; i < a.rows(); ++i) {
      const double d = std::abs(a(i, j) - b(i, j));
      if (!(d <= abs_tol + rel_tol * scale) || !std::isfinite(d)) {
        if (!(d <= worst)) {
          worst = d;
          wi = i;
          wj = j;
        }
      }
    }
  if (worst == 0) return ::testing::AssertionSuccess();
  std::ostringstream os;
  os.precision(17);
  os << "entry (" << wi << "," << wj << "): " << a(wi, wj) << " vs " << b(wi, wj) << ", |diff| = " << worst
     << " > " << abs_tol << " + " << rel_tol << " * " << scale;
  return ::testing::AssertionFailure() << os.str();
}

double rel_diff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double floor) {
  const double scale = std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), floor});
  return (a - b).cwiseAbs().maxCoeff() / scale;
}

Eigen::VectorXd random_vector(std::mt19937& rng, int n, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = u(rng);
  return v;
}

std::vector<RandomModelCase> random_model_family(std::mt19937& rng, const std::vector<int>& sizes,
                                                 const std::function<void(std::mt19937&, ModelDescription&)>& general_axes,
                                                 const std::string& general_label) {
  std::vector<RandomModelCase> out;
  const std::string kind[] = {"standard chain", "modified chain +fixed", "tree", general_label};
  for (int n : sizes)
    for (int variant = 0; variant < 4; ++variant) {
      RandomChainOptions o;
      o.dof = n;
      o.modified_dh = variant == 1;
      o.with_fixed_joints = variant == 1 || variant == 3;
      o.tree = variant >= 2;
      ModelDescription d = random_chain(rng, o);
      if (variant == 3) general_axes(rng, d);
      out.push_back({kind[variant] + " n=" + std::to_string(n), std::move(d)});
    }
  return out;
}

namespace {
Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Quaterniond qt(n(rng), n(rng), n(rng), n(rng));
  qt.normalize();
  return qt.toRotationMatrix();
}

LinkInertia random_inertia(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.2, 3.0), c(-0.3, 0.3), s(0.05, 0.5);
  LinkInertia in;
  in.mass = u(rng);
  in.com = Vec3(c(rng), c(rng), c(rng));
  // Box of random side lengths, rotated: always satisfies the triangle inequality.
  const double a = s(rng), b = s(rng), d = s(rng);
  Vec3 diag(in.mass * (b * b + d * d) / 12, in.mass * (a * a + d * d) / 12, in.mass * (a * a + b * b) / 12);
  const Mat3 R = random_rotation(rng);
  in.I_com = R * diag.asDiagonal() * R.transpose();
  in.I_com = 0.5 * (in.I_com + in.I_com.transpose()).eval();
  return in;
}
}  // namespace

std::vector<RandomModelCase> model_zoo(std::mt19937& rng, int dof, const ZooOptions& zoo) {
  std::vector<RandomModelCase> out;
  for (int variant = 0; variant < zoo.variants; ++variant) {
    RandomChainOptions o;
    o.dof = dof;
    o.prismatic_fraction = zoo.prismatic_fraction;
    o.modified_dh = variant & 1;
    o.tree = variant & 2;
    o.with_fixed_joints = variant & 4;
    std::string label = std::string(o.modified_dh ? "modified" : "standard") + (o.tree ? " tree" : " chain") +
                        (o.with_fixed_joints ? " +fixed" : "") + (zoo.dof_in_label ? " n=" + std::to_string(dof) : "");
    ModelDescription d = random_chain(rng, o);
    d.add_point("mid", d.links[d.links.size() / 2].name, zoo.mid);
    d.add_point("anchor", "world", zoo.anchor);
    out.push_back({label, d});
  }
  return out;
}

ModelDescription random_chain(std::mt19937& rng, const RandomChainOptions& opt) {
  std::uniform_real_distribution<double> ang(-3.14159, 3.14159), len(-0.6, 0.6), uni(0.0, 1.0);
  std::vector<DHRow> rows;
  for (int i = 0; i < opt.dof; ++i) {
    DHRow r;
    r.type = uni(rng) < opt.prismatic_fraction ? JointType::Prismatic : JointType::Revolute;
    r.theta = ang(rng);
    r.d = len(rng);
    r.a = len(rng);
    r.alpha = ang(rng);
    r.inertia = random_inertia(rng);
    rows.push_back(r);
  }
  ModelDescription d = from_dh(rows, opt.modified_dh ? DHConvention::Modified : DHConvention::Standard,
                               "random_chain");
  if (opt.tree) {
    for (size_t i = 1; i < d.links.size(); ++i)
      d.links[i].parent = std::uniform_int_distribution<int>(-1, static_cast<int>(i) - 1)(rng);
  }
  if (opt.with_fixed_joints) {
    // Insert a fixed link after every third link, carrying mass, reparenting the next one.
    ModelDescription e = d;
    e.links.clear();
    std::vector<int> map(d.links.size());
    for (size_t i = 0; i < d.links.size(); ++i) {
      LinkSpec l = d.links[i];
      l.parent = l.parent < 0 ? -1 : map[l.parent];
      map[i] = e.add_link(l);
      if (i % 3 == 1) {
        LinkSpec f;
        f.name = l.name + "_fixed";
        f.type = JointType::Fixed;
        f.parent = map[i];
        f.placement = SE3{random_rotation(rng), Vec3(len(rng), len(rng), len(rng))};
        f.inertia = random_inertia(rng);
        map[i] = e.add_link(f);  // children of link i hang from the fixed link
      }
    }
    d = e;
  }
  if (opt.random_base) d.base = SE3{random_rotation(rng), Vec3(len(rng), len(rng), len(rng))};
  d.gravity = Vec3(0.3, -0.2, -9.81);
  d.add_point("tip", d.links.back().name, Vec3(len(rng), len(rng), len(rng)));
  return d;
}

}  // namespace refdyn::test

namespace refdyn::test {

std::vector<SE3> reference_link_poses(const ModelDescription& d, const Eigen::VectorXd& q) {
  std::vector<SE3> T(d.links.size());
  Eigen::Index k = 0;
  for (size_t i = 0; i < d.links.size(); ++i) {
    const LinkSpec& l = d.links[i];
    const SE3 parent = l.parent < 0 ? d.base : T[static_cast<size_t>(l.parent)];
    SE3 J = SE3::Identity();
    if (l.type == JointType::Revolute) {
      J.R = Eigen::AngleAxisd(q[k++] + l.offset, l.axis.normalized()).toRotationMatrix();
    } else if (l.type == JointType::Prismatic) {
      J.p = l.axis.normalized() * (q[k++] + l.offset);
    }
    T[i] = parent * l.placement * J * l.link_offset;
  }
  return T;
}

Vec3 reference_point_position(const ModelDescription& d, const Eigen::VectorXd& q,
                              const std::string& point) {
  const std::vector<SE3> T = reference_link_poses(d, q);
  for (const PointSpec& p : d.points) {
    if (p.name != point) continue;
    if (p.link == "world") return p.position;
    if (p.link == "base") return d.base.act_point(p.position);
    for (size_t i = 0; i < d.links.size(); ++i)
      if (d.links[i].name == p.link) return T[i].act_point(p.position);
  }
  ADD_FAILURE() << "reference_point_position: no point '" << point << "'";
  return Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
}

std::vector<int> movable_links(const ModelDescription& d) {
  std::vector<int> out;
  for (size_t i = 0; i < d.links.size(); ++i)
    if (d.links[i].type != JointType::Fixed) out.push_back(static_cast<int>(i));
  return out;
}

ConstraintPtr renamed(NewConstraint c, const std::string& name) {
  c->name = name;
  return c;
}

void randomize_axes(std::mt19937& rng, ModelDescription& d) {
  std::normal_distribution<double> nd(0, 1);
  std::uniform_int_distribution<int> pick(0, 4);
  for (LinkSpec& l : d.links) {
    switch (pick(rng)) {
      case 0: l.axis = -Vec3::UnitZ(); break;
      case 1: l.axis = Vec3::UnitX(); break;
      case 2: l.axis = -Vec3::UnitY(); break;
      default: l.axis = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    }
  }
}

Vec3 random_unit(std::mt19937& rng) {
  Vec3 v = test::random_vector(rng, 3);
  while (v.norm() < 0.1) v = test::random_vector(rng, 3);
  return v.normalized();
}

/// Every ready-made kind of constraints.hpp.
ConstraintSet all_kinds(const Model& model, std::mt19937& rng) {
  ConstraintSet set;
  set.add(renamed(point_on_surface(model, "tip", elliptic_cylinder(0.7, 0.4, 0.1, -0.2)), "ellipse"));
  set.add(renamed(point_on_surface(model, "mid", sphere(Vec3(0.2, 0.1, -0.3), 0.8)), "sphere"));
  set.add(renamed(point_on_surface(model, "tip", plane(random_unit(rng), sinusoid(0.3, 2.0, 0.1, 0.2))),
                  "moving_plane"));
  set.add(point_coordinate(model, "tip", 0, sinusoid(0.2, 1.7, 0.3, 0.5)));
  set.add(point_coordinate(model, "mid", 2, raised_cosine(0.6, 0.1, 5.0)));
  set.add(joint_trajectory(model, model.joint_name[model.nq / 2], polynomial({0.2, -0.4, 0.3, 0.05})));
  set.add(joint_coupling(model, model.joint_name[0], model.joint_name[model.nq - 1], -1.7, 0.3));
  set.add(points_coincide(model, "tip", "mid"));
  set.add(points_coincide(model, "tip", "anchor", {0, 2}));
  set.add(knife_edge(model, "tip", random_unit(rng)));
  set.add(knife_edge(model, "mid", random_unit(rng)));
  set.add(renamed(point_speed(model, "tip", random_unit(rng), sinusoid(0.4, 2.3, -0.2, 0.1)), "speed_tip_a"));
  set.add(renamed(point_speed(model, "mid", random_unit(rng), polynomial({0.3, 0.2, -0.1})), "speed_mid"));
  return set;
}

}  // namespace refdyn::test

extern "C" const char* refdyn_test_source_dir() { return REFDYN_SOURCE_DIR_PATH; }
extern "C" const char* refdyn_test_cli() { return REFDYN_CLI_PATH; }
