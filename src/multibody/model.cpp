#include "refdyn/multibody/model.hpp"

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
    // The joint variable enters through θ (revolute) or d (prismatic); the other one is fixed.
    SE3 fixed_along_z = r.type == JointType::Prismatic ? SE3::rot_z(r.theta) : SE3::trans(Vec3(0, 0, r.d));
    if (r.type == JointType::Fixed) fixed_along_z = SE3::rot_z(r.theta) * SE3::trans(Vec3(0, 0, r.d));
    l.offset = r.type == JointType::Prismatic ? r.d : (r.type == JointType::Revolute ? r.theta : 0.0);
    SE3 x_part = SE3::trans(Vec3(r.a, 0, 0)) * SE3::rot_x(r.alpha);
    if (conv == DHConvention::Standard) {
      l.placement = fixed_along_z;
      l.link_offset = x_part;
    } else {
      l.placement = SE3::rot_x(r.alpha) * SE3::trans(Vec3(r.a, 0, 0)) * fixed_along_z;
      l.link_offset = SE3::Identity();
    }
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

/// Folds fixed joints: each link maps to a movable body (body_of, −1 = world) plus a fixed pose
/// of the link frame in that body's frame (link_in_body); the movable ones become m's bodies.
void fold_links(const ModelDescription& d, ModelData& m, std::vector<int>& body_of, std::vector<SE3>& link_in_body) {
  const int nl = static_cast<int>(d.links.size());
  for (int i = 0; i < nl; ++i) {
    const LinkSpec& l = d.links[i];
    // pose of the joint frame relative to the frame of the body the parent belongs to
    int pb = l.parent < 0 ? -1 : body_of[l.parent];
    SE3 parent_pose = l.parent < 0 ? d.base : link_in_body[l.parent];
    SE3 joint_in_pb = parent_pose * l.placement;
    Inertia I_link = Inertia::from_com(l.inertia.mass, l.inertia.com, l.inertia.I_com);
    if (l.type == JointType::Fixed) {
      body_of[i] = pb;
      link_in_body[i] = joint_in_pb * l.link_offset;
      if (pb >= 0) m.inertia[pb] += I_link.transformed(link_in_body[i]);
      continue;
    }
    int b = m.nq++;
    body_of[i] = b;
    link_in_body[i] = l.link_offset;
    m.parent.push_back(pb);
    m.joint_type.push_back(l.type);
    m.placement.push_back(joint_in_pb);
    m.axis.push_back(l.axis.normalized());
    m.offset.push_back(l.offset);
    m.inertia.push_back(I_link.transformed(l.link_offset));
    m.link_offset.push_back(l.link_offset);
    m.body_name.push_back(l.name);
    m.joint_name.push_back(l.joint_name.empty() ? l.name : l.joint_name);
    m.limits.push_back(l.limits);
  }
}

/// The named points of d, on the bodies their links were folded into.
void add_points(const ModelDescription& d, const std::map<std::string, int>& link_by_name,
                const std::vector<int>& body_of, const std::vector<SE3>& link_in_body, ModelData& m) {
  for (size_t k = 0; k < d.points.size(); ++k) {
    const PointSpec& p = d.points[k];
    std::string where = "point '" + p.name + "'";
    if (p.name.empty()) throw Error("point " + std::to_string(k) + ": expected a name, got an empty one");
    for (const auto& n : m.point_name)
      if (n == p.name) throw Error(where + ": duplicate point name");
    if (!p.position.allFinite()) throw Error(where + ": position must be finite");
    int body = -1;
    SE3 pose = SE3::Identity();
    if (p.link == "world" || p.link == "base") {
      pose = p.link == "base" ? d.base : SE3::Identity();
    } else {
      auto it = link_by_name.find(p.link);
      if (it == link_by_name.end()) {
        std::vector<std::string> names;
        for (const auto& l : d.links) names.push_back(l.name);
        throw Error(where + ": unknown link '" + p.link + "'" + did_you_mean(p.link, names));
      }
      body = body_of[it->second];
      pose = link_in_body[it->second];  // base already folded in for links fixed to the world
    }
    m.point_name.push_back(p.name);
    m.point_body.push_back(body);
    m.point_position.push_back(pose.act_point(p.position));
  }
}

}  // namespace

Model build_model(const ModelDescription& d) {
  check_finite_se3(d.base, "model base transform");
  if (!d.gravity.allFinite()) throw Error("model gravity: expected finite numbers, got NaN or infinity");
  const int nl = static_cast<int>(d.links.size());
  std::map<std::string, int> link_by_name;
  for (int i = 0; i < nl; ++i) validate_link(d, i, link_by_name);

  std::vector<int> body_of(nl, -1);
  std::vector<SE3> link_in_body(nl);  // pose of link frame in its body frame (or world)
  static std::atomic<std::uint64_t> next_id{1};
  ModelData m;
  m.id = next_id++;
  m.name = d.name;
  m.gravity = d.gravity;
  fold_links(d, m, body_of, link_in_body);
  m.nv = m.nq;
  m.armature.assign(m.nq, 0.0);
  for (int i = 0; i < nl; ++i)
    if (d.links[i].type != JointType::Fixed) m.armature[body_of[i]] = d.links[i].armature;
  for (int i = 0; i < nl; ++i) m.frame_name.push_back(d.links[i].name);
  m.frame_body = body_of;
  m.frame_pose = link_in_body;
  m.support.resize(m.nq);
  for (int i = 0; i < m.nq; ++i) {
    if (m.parent[i] >= 0) m.support[i] = m.support[m.parent[i]];
    m.support[i].push_back(i);
  }
  add_points(d, link_by_name, body_of, link_in_body, m);
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
