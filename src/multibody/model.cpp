#include "refdyn/multibody/model.hpp"

#include "refdyn/multibody/detail/fold.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Eigenvalues>
#include <atomic>
#include <cmath>
#include <map>
#include <sstream>

namespace refdyn {

const char* to_string(JointType t) {
  switch (t) {
    case JointType::Revolute: return "revolute";
    case JointType::Prismatic: return "prismatic";
    case JointType::Fixed: return "fixed";
  }
  return "?";
}

int ModelDescription::add_link(const LinkSpec& l) {
  links.push_back(l);
  return static_cast<int>(links.size()) - 1;
}

ModelDescription& ModelDescription::add_point(const std::string& n, const std::string& link,
                                              const Vec3& p) {
  points.push_back({n, link, p});
  return *this;
}

ModelDescription from_dh(const std::vector<DHRow>& rows, DHConvention conv, const std::string& name) {
  ModelDescription d;
  d.name = name;
  for (size_t i = 0; i < rows.size(); ++i) {
    const DHRow& r = rows[i];
    LinkSpec l;
    l.name = r.name.empty() ? "link" + std::to_string(i + 1) : r.name;
    l.joint_name = r.name.empty() ? "q" + std::to_string(i + 1) : r.name;
    l.parent = static_cast<int>(i) - 1;
    l.type = r.type;
    l.axis = Vec3::UnitZ();
    l.inertia = r.inertia;
    l.limits = r.limits;
    const multibody::DHFrames<double> f =
        multibody::dh_frames(r.type, r.theta, r.d, r.a, r.alpha, conv == DHConvention::Standard);
    l.placement = f.placement;
    l.link_offset = f.link_offset;
    l.offset = f.offset;
    d.add_link(l);
  }
  return d;
}

namespace {

void check_finite_se3(const SE3& X, const std::string& where) {
  if (!X.R.allFinite() || !X.p.allFinite())
    throw Error(where + ": expected finite numbers, got NaN or infinity");
  if ((X.R.transpose() * X.R - Mat3::Identity()).norm() > 1e-9 || X.R.determinant() < 0)
    throw Error(where + ": expected a proper rotation matrix (orthonormal, det +1)");
}

void validate_inertia(const LinkInertia& in, const std::string& link) {
  const std::string where = "link '" + link + "'";
  if (!std::isfinite(in.mass) || !in.com.allFinite() || !in.I_com.allFinite())
    throw Error(where + ": mass properties must be finite numbers, got NaN or infinity");
  if (in.mass < 0)
    throw Error(expected_got(where + " mass", "a value >= 0", fmt(in.mass),
                             "masses are in kg; use 0 for a massless link"));
  if ((in.I_com - in.I_com.transpose()).norm() > 1e-9 * (1 + in.I_com.norm()))
    throw Error(where + ": inertia tensor must be symmetric");
  Eigen::SelfAdjointEigenSolver<Mat3> es(in.I_com, Eigen::EigenvaluesOnly);
  Vec3 ev = es.eigenvalues();
  double tol = 1e-12 * (1 + ev.cwiseAbs().maxCoeff());
  if (ev.minCoeff() < -tol)
    throw Error(expected_got(where + " inertia about the centre of mass",
                             "a positive semi-definite tensor", "smallest eigenvalue " + fmt(ev.minCoeff()),
                             "inertias are in kg m² about the centre of mass, in link axes"));
  // Triangle inequality on principal moments: each <= sum of the two others.
  for (int k = 0; k < 3; ++k) {
    double others = ev.sum() - ev[k];
    if (ev[k] > others + tol)
      throw Error(expected_got(where + " principal moments of inertia",
                               "each at most the sum of the two others (triangle inequality)",
                               fmt(ev[0]) + ", " + fmt(ev[1]) + ", " + fmt(ev[2]),
                               "no physical body has these moments; check the tensor's entries"));
  }
  if (in.mass == 0 && in.I_com.norm() > 0)
    throw Error(where + ": a massless link cannot have rotational inertia");
}

/// Checks link i of d (name, parent, transforms, axis, inertia, limits) and records its name.
void validate_link(const ModelDescription& d, int i, std::map<std::string, int>& link_by_name) {
  const int nl = static_cast<int>(d.links.size());
  const LinkSpec& l = d.links[i];
  std::string where = "link " + std::to_string(i) + " ('" + l.name + "')";
  if (l.name.empty()) throw Error("link " + std::to_string(i) + ": expected a name, got an empty one");
  if (!link_by_name.emplace(l.name, i).second)
    throw Error(where + ": duplicate link name (hint: every link needs its own name)");
  if (l.parent < -1 || l.parent >= nl)
    throw Error(expected_got(where + " parent", "-1 (base) or an existing link index",
                             std::to_string(l.parent)));
  if (l.parent >= i)
    throw Error(expected_got(where + " parent", "a link listed before it (index < " + std::to_string(i) + ")",
                             std::to_string(l.parent), "list parents before their children"));
  check_finite_se3(l.placement, where + " placement");
  check_finite_se3(l.link_offset, where + " link offset");
  if (!std::isfinite(l.offset)) throw Error(where + ": joint offset must be finite");
  if (l.type != JointType::Fixed) {
    if (!l.axis.allFinite() || l.axis.norm() < 1e-12)
      throw Error(expected_got(where + " joint axis", "a non-zero finite vector", "zero or NaN"));
  }
  validate_inertia(l.inertia, l.name);
  const JointLimits& lim = l.limits;
  if (std::isnan(lim.lower) || std::isnan(lim.upper) || std::isnan(lim.velocity) || std::isnan(lim.effort))
    throw Error(where + " limits: NaN is not a limit (leave a limit out to mean 'unlimited')");
  if (lim.lower > lim.upper)
    throw Error(expected_got(where + " position limits", "lower <= upper", fmt(lim.lower) + " > " + fmt(lim.upper)));
  if (lim.velocity < 0 || lim.effort < 0)
    throw Error(where + " limits: velocity and effort limits must be >= 0");
  if (!std::isfinite(l.armature) || l.armature < 0)
    throw Error(expected_got(where + " armature", "a finite value >= 0", fmt(l.armature),
                             "the rotor inertia reflected to the joint, I_r N² [kg m²] (kg for a prismatic joint)"));
  if (l.type == JointType::Fixed && l.armature != 0)
    throw Error(where + ": a fixed joint has no armature (hint: remove it, or give the joint a type that moves)");
}

/// The links as the fold (multibody/detail/fold.hpp) reads them.
std::vector<multibody::FoldLink<double>> fold_input(const ModelDescription& d) {
  std::vector<multibody::FoldLink<double>> links;
  for (const LinkSpec& l : d.links)
    links.push_back({l.parent, l.type, l.placement, l.link_offset,
                     Inertia::from_com(l.inertia.mass, l.inertia.com, l.inertia.I_com)});
  return links;
}

/// The bodies of the folded links: m's per-body members.
void add_bodies(const ModelDescription& d, const multibody::Folded<double>& f, ModelData& m) {
  for (int b = 0; b < f.size(); ++b) {
    const LinkSpec& l = d.links[f.link_of_body[b]];
    m.parent.push_back(f.parent[b]);
    m.joint_type.push_back(l.type);
    m.placement.push_back(f.placement[b]);
    m.axis.push_back(l.axis.normalized());
    m.offset.push_back(l.offset);
    m.inertia.push_back(f.inertia[b]);
    m.link_offset.push_back(l.link_offset);
    m.body_name.push_back(l.name);
    m.joint_name.push_back(l.joint_name.empty() ? l.name : l.joint_name);
    m.limits.push_back(l.limits);
    m.armature.push_back(l.armature);
  }
  m.nq = m.nv = f.size();
}

/// The named points of d, on the bodies their links were folded into.
void add_points(const ModelDescription& d, const std::map<std::string, int>& link_by_name,
                const multibody::Folded<double>& f, ModelData& m) {
  for (size_t k = 0; k < d.points.size(); ++k) {
    const PointSpec& p = d.points[k];
    std::string where = "point '" + p.name + "'";
    if (p.name.empty()) throw Error("point " + std::to_string(k) + ": expected a name, got an empty one");
    for (const auto& n : m.point_name)
      if (n == p.name) throw Error(where + ": duplicate point name");
    if (!p.position.allFinite()) throw Error(where + ": position must be finite");
    int link = p.link == "world" ? multibody::kOnWorld : multibody::kOnBase;
    if (p.link != "world" && p.link != "base") {
      auto it = link_by_name.find(p.link);
      if (it == link_by_name.end()) {
        std::vector<std::string> names;
        for (const auto& l : d.links) names.push_back(l.name);
        throw Error(where + ": unknown link '" + p.link + "'" + did_you_mean(p.link, names));
      }
      link = it->second;
    }
    const multibody::FoldedPoint<double> fp = multibody::place_point(f, link, d.base, p.position);
    m.point_name.push_back(p.name);
    m.point_body.push_back(fp.body);
    m.point_position.push_back(fp.position);
  }
}

}  // namespace

Model build_model(const ModelDescription& d) {
  check_finite_se3(d.base, "model base transform");
  if (!d.gravity.allFinite()) throw Error("model gravity: expected finite numbers, got NaN or infinity");
  const int nl = static_cast<int>(d.links.size());
  std::map<std::string, int> link_by_name;
  for (int i = 0; i < nl; ++i) validate_link(d, i, link_by_name);

  static std::atomic<std::uint64_t> next_id{1};
  ModelData m;
  m.id = next_id++;
  m.name = d.name;
  m.gravity = d.gravity;
  const multibody::Folded<double> f = multibody::fold_links(fold_input(d), d.base);
  add_bodies(d, f, m);
  for (int i = 0; i < nl; ++i) m.frame_name.push_back(d.links[i].name);
  m.frame_body = f.body_of;
  m.frame_pose = f.link_in_body;
  m.support.resize(m.nq);
  for (int i = 0; i < m.nq; ++i) {
    if (m.parent[i] >= 0) m.support[i] = m.support[m.parent[i]];
    m.support[i].push_back(i);
  }
  add_points(d, link_by_name, f, m);
  return Model(std::move(m));
}

Model::Model(ModelData d)
    : nq(d.nq), nv(d.nv), name(std::move(d.name)), id(d.id), gravity(d.gravity), parent(std::move(d.parent)),
      joint_type(std::move(d.joint_type)), placement(std::move(d.placement)), axis(std::move(d.axis)),
      offset(std::move(d.offset)), inertia(std::move(d.inertia)), link_offset(std::move(d.link_offset)),
      body_name(std::move(d.body_name)), joint_name(std::move(d.joint_name)), limits(std::move(d.limits)),
      support(std::move(d.support)), armature(std::move(d.armature)), point_name(std::move(d.point_name)),
      point_body(std::move(d.point_body)), point_position(std::move(d.point_position)),
      frame_name(std::move(d.frame_name)), frame_body(std::move(d.frame_body)), frame_pose(std::move(d.frame_pose)) {}

int Model::body_index(const std::string& n) const { return find_name(body_name, n, "link"); }
int Model::point_index(const std::string& n) const { return find_name(point_name, n, "point"); }
int Model::joint_index(const std::string& n) const { return find_name(joint_name, n, "joint"); }

Mat4 Model::pseudo_inertia(int i) const {
  const Inertia& I = inertia[i];
  Mat4 H = Mat4::Zero();
  H.topLeftCorner<3, 3>() = 0.5 * I.I.trace() * Mat3::Identity() - I.I;
  H.topRightCorner<3, 1>() = I.h;
  H.bottomLeftCorner<1, 3>() = I.h.transpose();
  H(3, 3) = I.m;
  return H;
}

double Model::total_mass() const {
  double s = 0;
  for (const auto& I : inertia) s += I.m;
  return s;
}

std::string Model::summary() const {
  std::ostringstream os;
  os << "model '" << name << "': " << nq << " degrees of freedom, total mass " << total_mass() << " kg\n";
  for (int i = 0; i < nq; ++i) {
    os << "  " << i << "  " << joint_name[i] << "  " << to_string(joint_type[i]) << "  link '" << body_name[i]
       << "'  parent " << (parent[i] < 0 ? std::string("base") : body_name[parent[i]]) << "  mass "
       << inertia[i].m << " kg";
    if (armature[i] != 0) os << "  armature " << armature[i] << (joint_type[i] == JointType::Revolute ? " kg m^2" : " kg");
    os << "\n";
  }
  for (size_t k = 0; k < point_name.size(); ++k)
    os << "  point '" << point_name[k] << "' on "
       << (point_body[k] < 0 ? std::string("world") : body_name[point_body[k]]) << "\n";
  return os.str();
}

void check_data(const Model& model, const Data& data) {
  if (data.model_id == model.id && data.nq == model.nq) return;
  throw Error("this Data was built for another model (" + std::to_string(data.nq) + " coordinates) than model '" +
              model.name + "' (" + std::to_string(model.nq) +
              " coordinates); hint: create one workspace per model, refdyn::Data data(model)");
}

void Model::check_q(const Eigen::VectorXd& q, const char* what) const {
  check_vector(what, q, nq, "one entry per joint, in the model's joint order");
}

Data::Data(const Model& model)
    : model_id(model.id), nq(model.nq), liMi(model.nq), oMi(model.nq), v(model.nq), a(model.nq), f(model.nq),
      tau(Eigen::VectorXd::Zero(model.nq)), nle(Eigen::VectorXd::Zero(model.nq)),
      g(Eigen::VectorXd::Zero(model.nq)), Ic(model.nq), M(Eigen::MatrixXd::Zero(model.nq, model.nq)),
      llt(model.nq), ddq(Eigen::VectorXd::Zero(model.nq)), aba(model.nq), T(model.nq, Mat4::Identity()),
      D(model.nq, Mat4::Zero()), H(model.nq), Tdd(model.nq), Td(model.nq),
      M_trace(Eigen::MatrixXd::Zero(model.nq, model.nq)), c_trace(Eigen::VectorXd::Zero(model.nq)),
      g_trace(Eigen::VectorXd::Zero(model.nq)), Jp(3, model.nq), Jw(3, model.nq) {
  for (int i = 0; i < model.nq; ++i) H[i] = model.pseudo_inertia(i);
  Jp.setZero();
  Jw.setZero();
}

}  // namespace refdyn
