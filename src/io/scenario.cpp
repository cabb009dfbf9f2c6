#include "refdyn/io/scenario.hpp"

#include "refdyn/error.hpp"
#include "refdyn/expression.hpp"
#include "refdyn/io/urdf.hpp"
#include "refdyn/text.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>

namespace refdyn::io {

namespace {

namespace fs = std::filesystem;

class Ctx {
 public:
  explicit Ctx(std::string file) : file_(std::move(file)) {}
  const std::string& file() const { return file_; }
  std::map<std::string, double> params;

  [[noreturn]] void fail(const YAML::Node& at, const std::string& key, const std::string& msg) const {
    std::string where = file_;
    if (at.IsDefined() && !at.Mark().is_null()) where += ":" + std::to_string(at.Mark().line + 1);
    throw Error(where + ": " + (key.empty() ? std::string() : key + ": ") + one_line(msg));
  }

  /// Messages are one line: multi-line diagnostics (e.g. an expression with a ^^^ marker under
  /// it) are joined with "; " and marker-only lines dropped.
  static std::string one_line(const std::string& msg) {
    std::string out, line;
    std::istringstream is(msg);
    while (std::getline(is, line)) {
      const auto b = line.find_first_not_of(" \t");
      if (b == std::string::npos) continue;
      line = line.substr(b);
      if (line.find_first_not_of("^~ ") == std::string::npos) continue;
      out += (out.empty() ? "" : "; ") + line;
    }
    return out;
  }

  void keys(const YAML::Node& n, const std::string& key, const std::vector<std::string>& allowed) const {
    if (!n.IsMap()) fail(n, key, "expected a mapping (key: value lines), got " + kind(n));
    for (const auto& kv : n) {
      const std::string k = kv.first.as<std::string>();
      if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
        fail(kv.first, key.empty() ? k : key + "." + k, "unknown key '" + k + "'" + did_you_mean(k, allowed));
    }
  }

  static std::string kind(const YAML::Node& n) {
    if (!n.IsDefined() || n.IsNull()) return "nothing";
    if (n.IsScalar()) return "'" + n.Scalar() + "'";
    if (n.IsSequence()) return "a list";
    return "a mapping";
  }

  YAML::Node need(const YAML::Node& parent, const std::string& k, const std::string& key) const {
    const YAML::Node n = parent[k];
    if (!n.IsDefined() || n.IsNull()) fail(parent, key.empty() ? k : key + "." + k, "missing (this key is required)");
    return n;
  }

  double number(const YAML::Node& n, const std::string& key, const std::map<std::string, double>* extra = nullptr) const {
    if (!n.IsScalar()) fail(n, key, "expected a number or an expression, got " + kind(n));
    const std::string s = n.Scalar();
    double v = 0;
    const char* b = s.data();
    const char* e = s.data() + s.size();
    auto r = std::from_chars(b, e, v);
    if (r.ec == std::errc() && r.ptr == e) {
      if (!std::isfinite(v)) fail(n, key, "expected a finite number, got " + s);
      return v;
    }
    {  // YAML's special floats: .nan, .inf, -.inf (any case)
      std::string low;
      for (char ch : s) low += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (low == ".nan" || low == ".inf" || low == "+.inf" || low == "-.inf" || low == "nan" || low == "inf" ||
          low == "-inf")
        fail(n, key, "expected a finite number, got " + s);
    }
    std::map<std::string, double> p = params;
    if (extra) p.insert(extra->begin(), extra->end());
    try {
      const Expression ex(s, {}, p, 0);
      v = ex.value(nullptr);
    } catch (const Error& err) {
      fail(n, key, std::string("expected a number or an expression of the parameters: ") + err.what());
    }
    if (!std::isfinite(v)) fail(n, key, "the expression '" + s + "' is not a finite number");
    return v;
  }

  double number_or(const YAML::Node& parent, const std::string& k, const std::string& key, double dflt) const {
    const YAML::Node n = parent[k];
    return (n.IsDefined() && !n.IsNull()) ? number(n, key + "." + k) : dflt;
  }

  std::string string(const YAML::Node& n, const std::string& key) const {
    if (!n.IsScalar()) fail(n, key, "expected a text value, got " + kind(n));
    return n.Scalar();
  }

  bool boolean(const YAML::Node& n, const std::string& key) const {
    const std::string s = string(n, key);
    if (s == "true" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "no" || s == "off") return false;
    fail(n, key, "expected true or false, got '" + s + "'");
  }

  std::string choice(const YAML::Node& n, const std::string& key, const std::vector<std::string>& options) const {
    const std::string s = string(n, key);
    if (std::find(options.begin(), options.end(), s) == options.end()) {
      std::string all;
      for (const auto& o : options) all += (all.empty() ? "" : ", ") + o;
      fail(n, key, "expected one of " + all + ", got '" + s + "'" + did_you_mean(s, options));
    }
    return s;
  }

  Vec3 vec3(const YAML::Node& n, const std::string& key) const {
    if (!n.IsSequence() || n.size() != 3) fail(n, key, "expected a list of 3 numbers, got " + kind(n) + (n.IsSequence() ? " of " + std::to_string(n.size()) : ""));
    return Vec3(number(n[0], key + "[0]"), number(n[1], key + "[1]"), number(n[2], key + "[2]"));
  }

  SE3 pose(const YAML::Node& n, const std::string& key) const {
    keys(n, key, {"xyz", "rpy"});
    SE3 X;
    if (n["xyz"]) X.p = vec3(n["xyz"], key + ".xyz");
    if (n["rpy"]) {
      const Vec3 r = vec3(n["rpy"], key + ".rpy");  // URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)
      X.R = (Eigen::AngleAxisd(r.z(), Vec3::UnitZ()) * Eigen::AngleAxisd(r.y(), Vec3::UnitY()) *
             Eigen::AngleAxisd(r.x(), Vec3::UnitX()))
                .toRotationMatrix();
    }
    return X;
  }

  // A per-joint vector given as a list (model order) or a mapping by joint name.
  Eigen::VectorXd joint_vector(const YAML::Node& n, const std::string& key, const Model& m, bool all_required,
                               double dflt, const std::map<std::string, double>* extra = nullptr) const {
    Eigen::VectorXd v = Eigen::VectorXd::Constant(m.nq, dflt);
    if (n.IsSequence()) {
      if (static_cast<int>(n.size()) != m.nq)
        fail(n, key, "expected " + std::to_string(m.nq) + " values (one per joint: " + joint_list(m) + "), got " +
                         std::to_string(n.size()));
      for (int i = 0; i < m.nq; ++i) v[i] = number(n[i], key + "[" + std::to_string(i) + "]", extra);
      return v;
    }
    if (!n.IsMap()) fail(n, key, "expected a list of numbers or a mapping joint: value, got " + kind(n));
    std::vector<bool> seen(m.nq, false);
    for (const auto& kv : n) {
      const std::string j = kv.first.as<std::string>();
      int idx = -1;
      for (int i = 0; i < m.nq; ++i)
        if (m.joint_name[i] == j) idx = i;
      if (idx < 0) fail(kv.first, key + "." + j, "unknown joint '" + j + "'" + did_you_mean(j, m.joint_name));
      v[idx] = number(kv.second, key + "." + j, extra);
      seen[idx] = true;
    }
    if (all_required)
      for (int i = 0; i < m.nq; ++i)
        if (!seen[i]) fail(n, key, "missing a value for joint '" + m.joint_name[i] + "' (give all of: " + joint_list(m) + ")");
    return v;
  }

  static std::string joint_list(const Model& m) {
    std::string s;
    for (const auto& j : m.joint_name) s += (s.empty() ? "" : ", ") + j;
    return s;
  }

 private:
  std::string file_;
};

LinkInertia read_inertia(const Ctx& c, const YAML::Node& n, const std::string& key) {
  LinkInertia in;
  if (n["mass"]) in.mass = c.number(n["mass"], key + ".mass");
  if (in.mass < 0) c.fail(n["mass"], key + ".mass", "expected a number >= 0 [kg], got " + fmt(in.mass));
  if (n["com"]) in.com = c.vec3(n["com"], key + ".com");
  if (const YAML::Node I = n["inertia"]) {
    const std::string k = key + ".inertia";
    if (!I.IsSequence()) c.fail(I, k, "expected [Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] or a 3x3 list, got " + Ctx::kind(I));
    if (I.size() == 3 && I[0].IsSequence()) {
      for (int r = 0; r < 3; ++r) {
        const Vec3 row = c.vec3(I[r], k + "[" + std::to_string(r) + "]");
        in.I_com.row(r) = row.transpose();
      }
    } else if (I.size() == 3) {
      in.I_com = c.vec3(I, k).asDiagonal();
    } else if (I.size() == 6) {
      double v[6];
      for (int i = 0; i < 6; ++i) v[i] = c.number(I[i], k + "[" + std::to_string(i) + "]");
      in.I_com << v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2];
    } else {
      c.fail(I, k, "expected 3 (diagonal), 6 (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) or 3x3 values, got " + std::to_string(I.size()));
    }
  }
  return in;
}

JointLimits read_limits(const Ctx& c, const YAML::Node& n, const std::string& key) {
  JointLimits l;
  if (!n) return l;
  c.keys(n, key, {"lower", "upper", "velocity", "effort"});
  l.lower = c.number_or(n, "lower", key, l.lower);
  l.upper = c.number_or(n, "upper", key, l.upper);
  l.velocity = c.number_or(n, "velocity", key, l.velocity);
  l.effort = c.number_or(n, "effort", key, l.effort);
  return l;
}

JointType read_joint_type(const Ctx& c, const YAML::Node& n, const std::string& key) {
  const std::string t = c.choice(n, key, {"revolute", "prismatic", "fixed"});
  return t == "revolute" ? JointType::Revolute : t == "prismatic" ? JointType::Prismatic : JointType::Fixed;
}

ModelDescription read_model(const Ctx& c, const YAML::Node& m, std::map<std::string, int>& link_lines,
                            std::vector<UrdfMimic>& mimics) {
  const std::string key = "model";
  c.keys(m, key, {"name", "gravity", "base", "dh", "links", "urdf", "points"});
  const int sources = (m["dh"] ? 1 : 0) + (m["links"] ? 1 : 0) + (m["urdf"] ? 1 : 0);
  if (sources != 1) c.fail(m, key, "expected exactly one of 'dh', 'links' or 'urdf', got " + std::to_string(sources));
  ModelDescription d;
  if (const YAML::Node dh = m["dh"]) {
    c.keys(dh, "model.dh", {"convention", "joints"});
    DHConvention conv = DHConvention::Standard;
    if (dh["convention"]) conv = c.choice(dh["convention"], "model.dh.convention", {"standard", "modified"}) == "standard"
                                     ? DHConvention::Standard : DHConvention::Modified;
    const YAML::Node js = c.need(dh, "joints", "model.dh");
    if (!js.IsSequence() || js.size() == 0) c.fail(js, "model.dh.joints", "expected a non-empty list of joints");
    std::vector<DHRow> rows;
    std::vector<std::string> link_names;
    for (size_t i = 0; i < js.size(); ++i) {
      const YAML::Node j = js[i];
      const std::string k = "model.dh.joints[" + std::to_string(i) + "]";
      c.keys(j, k, {"name", "link", "type", "theta", "d", "a", "alpha", "mass", "com", "inertia", "limits"});
      DHRow r;
      r.name = c.string(c.need(j, "name", k), k + ".name");
      r.type = read_joint_type(c, c.need(j, "type", k), k + ".type");
      r.theta = c.number_or(j, "theta", k, 0.0);
      r.d = c.number_or(j, "d", k, 0.0);
      r.a = c.number_or(j, "a", k, 0.0);
      r.alpha = c.number_or(j, "alpha", k, 0.0);
      r.inertia = read_inertia(c, j, k);
      r.limits = read_limits(c, j["limits"], k + ".limits");
      rows.push_back(r);
      link_names.push_back(j["link"] ? c.string(j["link"], k + ".link") : r.name);
      link_lines[link_names.back()] = j.Mark().line + 1;
    }
    d = from_dh(rows, conv);
    for (size_t i = 0; i < rows.size(); ++i) {
      d.links[i].name = link_names[i];
      d.links[i].joint_name = rows[i].name;
    }
  } else if (const YAML::Node ls = m["links"]) {
    if (!ls.IsSequence() || ls.size() == 0) c.fail(ls, "model.links", "expected a non-empty list of links");
    std::map<std::string, int> index;
    for (size_t i = 0; i < ls.size(); ++i) {
      const YAML::Node l = ls[i];
      const std::string k = "model.links[" + std::to_string(i) + "]";
      c.keys(l, k, {"name", "joint", "parent", "type", "axis", "origin", "link_offset", "offset", "mass", "com", "inertia", "limits"});
      LinkSpec s;
      s.name = c.string(c.need(l, "name", k), k + ".name");
      s.joint_name = l["joint"] ? c.string(l["joint"], k + ".joint") : s.name;
      if (l["parent"]) {
        const std::string p = c.string(l["parent"], k + ".parent");
        if (p != "base" && p != "world") {
          auto it = index.find(p);
          if (it == index.end()) {
            std::vector<std::string> names;
            for (auto& [nm, ix] : index) names.push_back(nm);
            c.fail(l["parent"], k + ".parent", "unknown parent link '" + p + "' (links must be listed after their parent)" + did_you_mean(p, names));
          }
          s.parent = it->second;
        }
      }
      s.type = read_joint_type(c, c.need(l, "type", k), k + ".type");
      if (l["axis"]) s.axis = c.vec3(l["axis"], k + ".axis");
      if (s.axis.norm() < 1e-12) c.fail(l["axis"], k + ".axis", "expected a non-zero vector");
      if (l["origin"]) s.placement = c.pose(l["origin"], k + ".origin");
      if (l["link_offset"]) s.link_offset = c.pose(l["link_offset"], k + ".link_offset");
      s.offset = c.number_or(l, "offset", k, 0.0);
      s.inertia = read_inertia(c, l, k);
      s.limits = read_limits(c, l["limits"], k + ".limits");
      index[s.name] = static_cast<int>(d.links.size());
      link_lines[s.name] = l.Mark().line + 1;
      d.add_link(s);
    }
  } else {
    const YAML::Node u = m["urdf"];
    c.keys(u, "model.urdf", {"file", "root"});
    std::string f = c.string(c.need(u, "file", "model.urdf"), "model.urdf.file");
    fs::path p(f);
    if (p.is_relative()) p = fs::path(c.file()).parent_path() / p;
    UrdfOptions uo;
    if (u["root"]) uo.root_link = c.string(u["root"], "model.urdf.root");
    try {
      d = load_urdf(p.string(), uo, &mimics);
    } catch (const Error& e) {
      c.fail(u["file"], "model.urdf.file", e.what());
    }
  }
  if (m["name"]) d.name = c.string(m["name"], "model.name");
  if (m["gravity"]) d.gravity = c.vec3(m["gravity"], "model.gravity");
  if (m["base"]) d.base = c.pose(m["base"], "model.base");
  if (const YAML::Node ps = m["points"]) {
    if (!ps.IsMap()) c.fail(ps, "model.points", "expected a mapping name: {link: ..., position: [x, y, z]}");
    for (const auto& kv : ps) {
      const std::string name = kv.first.as<std::string>();
      const std::string k = "model.points." + name;
      c.keys(kv.second, k, {"link", "position"});
      const std::string link = c.string(c.need(kv.second, "link", k), k + ".link");
      Vec3 pos = Vec3::Zero();
      if (kv.second["position"]) pos = c.vec3(kv.second["position"], k + ".position");
      bool known = link == "world" || link == "base";
      std::vector<std::string> names;
      for (const auto& l : d.links) {
        names.push_back(l.name);
        known = known || l.name == link;
      }
      if (!known) c.fail(kv.second["link"], k + ".link", "unknown link '" + link + "'" + did_you_mean(link, names));
      // A point named like an existing one (e.g. URDF link points) replaces it.
      std::erase_if(d.points, [&](const PointSpec& s) { return s.name == name; });
      d.add_point(name, link, pos);
    }
  }
  return d;
}

TimeFunctionPtr read_time_function(const Ctx& c, const YAML::Node& n, const std::string& key) {
  if (n.IsScalar()) {
    double v = 0;
    const std::string s = n.Scalar();
    auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec == std::errc() && r.ptr == s.data() + s.size()) return constant(v);
    try {
      return expression_time_function(s, c.params);
    } catch (const Error& e) {
      c.fail(n, key, e.what());
    }
  }
  if (n.IsMap()) {
    c.keys(n, key, {"cycloidal"});
    const YAML::Node cy = n["cycloidal"];
    const std::string k = key + ".cycloidal";
    c.keys(cy, k, {"rise", "duration", "from", "start"});
    const double rise = c.number(c.need(cy, "rise", k), k + ".rise");
    const double dur = c.number(c.need(cy, "duration", k), k + ".duration");
    if (!(dur > 0)) c.fail(cy["duration"], k + ".duration", "expected a duration > 0 [s], got " + fmt(dur));
    return cycloidal(rise, dur, c.number_or(cy, "from", k, 0.0), c.number_or(cy, "start", k, 0.0));
  }
  c.fail(n, key, "expected a number, an expression in t, or {cycloidal: {rise, duration}}, got " + Ctx::kind(n));
}

void read_forces(const Ctx& c, const YAML::Node& n, const std::string& key, const Model& m, ForceSet& out) {
  if (!n || n.IsNull()) return;
  if (n.IsScalar() && n.Scalar() == "none") return;
  if (!n.IsSequence()) c.fail(n, key, "expected a list of force elements (or 'none'), got " + Ctx::kind(n));
  for (size_t i = 0; i < n.size(); ++i) {
    const YAML::Node f = n[i];
    const std::string k = key + "[" + std::to_string(i) + "]";
    if (!f.IsMap()) c.fail(f, k, "expected a mapping with a 'type', got " + Ctx::kind(f));
    const std::string type = c.choice(c.need(f, "type", k), k + ".type", {"flexible_drive", "lugre", "damping", "spring", "effort"});
    const std::string joint = c.string(c.need(f, "joint", k), k + ".joint");
    if (std::find(m.joint_name.begin(), m.joint_name.end(), joint) == m.joint_name.end())
      c.fail(f["joint"], k + ".joint", "unknown joint '" + joint + "'" + did_you_mean(joint, m.joint_name));
    try {
      if (type == "flexible_drive") {
        c.keys(f, k, {"type", "joint", "stiffness", "damping", "profile"});
        FlexibleDriveParams p{c.number(c.need(f, "stiffness", k), k + ".stiffness"), c.number(c.need(f, "damping", k), k + ".damping")};
        out.add(std::make_shared<FlexibleDrive>(m, joint, p, read_time_function(c, c.need(f, "profile", k), k + ".profile")));
      } else if (type == "lugre") {
        c.keys(f, k, {"type", "joint", "mu_s", "mu_k", "sigma0", "sigma1", "sigma2", "stribeck_velocity"});
        LuGreParams p;
        p.mu_s = c.number(c.need(f, "mu_s", k), k + ".mu_s");
        p.mu_k = c.number(c.need(f, "mu_k", k), k + ".mu_k");
        p.sigma0 = c.number(c.need(f, "sigma0", k), k + ".sigma0");
        p.sigma1 = c.number_or(f, "sigma1", k, 0.0);
        p.sigma2 = c.number_or(f, "sigma2", k, 0.0);
        p.v_stribeck = c.number(c.need(f, "stribeck_velocity", k), k + ".stribeck_velocity");
        out.add(std::make_shared<LuGreFriction>(m, joint, p));
      } else if (type == "damping") {
        c.keys(f, k, {"type", "joint", "coefficient"});
        out.add(joint_damping(m, joint, c.number(c.need(f, "coefficient", k), k + ".coefficient")));
      } else if (type == "spring") {
        c.keys(f, k, {"type", "joint", "stiffness", "rest"});
        out.add(joint_spring(m, joint, c.number(c.need(f, "stiffness", k), k + ".stiffness"), c.number_or(f, "rest", k, 0.0)));
      } else {
        c.keys(f, k, {"type", "joint", "value"});
        out.add(joint_effort(m, joint, read_time_function(c, c.need(f, "value", k), k + ".value")));
      }
    } catch (const Error& e) {
      const std::string w = e.what();
      if (w.rfind(c.file(), 0) == 0) throw;  // already located
      c.fail(f, k, w);
    }
  }
}

int axis_index(const Ctx& c, const YAML::Node& n, const std::string& key) {
  const std::string a = c.choice(n, key, {"x", "y", "z"});
  return a[0] - 'x';
}

void read_constraints(const Ctx& c, const YAML::Node& n, const Model& m, ConstraintSet& out) {
  if (!n || n.IsNull()) return;
  if (!n.IsSequence()) c.fail(n, "constraints", "expected a list of constraints, got " + Ctx::kind(n));
  for (size_t i = 0; i < n.size(); ++i) {
    const YAML::Node e = n[i];
    const std::string k = "constraints[" + std::to_string(i) + "]";
    if (!e.IsMap()) c.fail(e, k, "expected a mapping with 'name' and 'expression' or 'kind', got " + Ctx::kind(e));
    const std::string name = c.string(c.need(e, "name", k), k + ".name");
    const std::string kk = "constraints." + name;
    // Default origin: material for the physical kinds (loop closure, knife edge), else programmed.
    const bool physical = e["kind"] && e["kind"].IsScalar() &&
                          (e["kind"].Scalar() == "points_coincide" || e["kind"].Scalar() == "knife_edge" ||
                           e["kind"].Scalar() == "joint_coupling");
    const ConstraintOrigin origin =
        e["origin"] ? (c.choice(e["origin"], kk + ".origin", {"material", "programmed"}) == "material"
                           ? ConstraintOrigin::Material : ConstraintOrigin::Programmed)
                    : (physical ? ConstraintOrigin::Material : ConstraintOrigin::Programmed);
    auto point = [&](const char* field) {
      const std::string p = c.string(c.need(e, field, kk), kk + "." + field);
      if (std::find(m.point_name.begin(), m.point_name.end(), p) == m.point_name.end())
        c.fail(e[field], kk + "." + field, "unknown point '" + p + "'" + did_you_mean(p, m.point_name) + " (define it under model.points)");
      return p;
    };
    ConstraintPtr con;
    try {
      if (e["expression"]) {
        c.keys(e, k, {"name", "origin", "expression", "order"});
        bool first = false;
        if (e["order"]) first = c.choice(e["order"], kk + ".order", {"position", "velocity"}) == "velocity";
        con = expression_constraint(m, name, c.string(e["expression"], kk + ".expression"), first, c.params, origin);
      } else {
        const std::vector<std::string> kinds{"point_on_ellipse", "point_on_sphere", "point_coordinate", "joint_trajectory",
                                             "joint_coupling", "points_coincide", "knife_edge", "point_speed"};
        const std::string kind = c.choice(c.need(e, "kind", k), kk + ".kind", kinds);
        if (kind == "point_on_ellipse") {
          c.keys(e, k, {"name", "origin", "kind", "point", "a", "b", "center"});
          Vec3 ctr = Vec3::Zero();
          if (e["center"]) {
            const YAML::Node cn = e["center"];
            if (!cn.IsSequence() || cn.size() != 2) c.fail(cn, kk + ".center", "expected [cx, cy]");
            ctr = Vec3(c.number(cn[0], kk + ".center[0]"), c.number(cn[1], kk + ".center[1]"), 0);
          }
          con = point_on_surface(m, point("point"), elliptic_cylinder(c.number(c.need(e, "a", kk), kk + ".a"),
                                                                      c.number(c.need(e, "b", kk), kk + ".b"), ctr.x(), ctr.y()), origin);
        } else if (kind == "point_on_sphere") {
          c.keys(e, k, {"name", "origin", "kind", "point", "center", "radius"});
          con = point_on_surface(m, point("point"), sphere(c.vec3(c.need(e, "center", kk), kk + ".center"),
                                                           c.number(c.need(e, "radius", kk), kk + ".radius")), origin);
        } else if (kind == "point_coordinate") {
          c.keys(e, k, {"name", "origin", "kind", "point", "axis", "function"});
          con = point_coordinate(m, point("point"), axis_index(c, c.need(e, "axis", kk), kk + ".axis"),
                                 read_time_function(c, c.need(e, "function", kk), kk + ".function"), origin);
        } else if (kind == "joint_trajectory") {
          c.keys(e, k, {"name", "origin", "kind", "joint", "function"});
          const std::string j = c.string(c.need(e, "joint", kk), kk + ".joint");
          if (std::find(m.joint_name.begin(), m.joint_name.end(), j) == m.joint_name.end())
            c.fail(e["joint"], kk + ".joint", "unknown joint '" + j + "'" + did_you_mean(j, m.joint_name));
          con = joint_trajectory(m, j, read_time_function(c, c.need(e, "function", kk), kk + ".function"), origin);
        } else if (kind == "joint_coupling") {
          c.keys(e, k, {"name", "origin", "kind", "joint", "leader", "ratio", "offset"});
          auto joint = [&](const char* field) {
            const std::string j = c.string(c.need(e, field, kk), kk + "." + field);
            if (std::find(m.joint_name.begin(), m.joint_name.end(), j) == m.joint_name.end())
              c.fail(e[field], kk + "." + field, "unknown joint '" + j + "'" + did_you_mean(j, m.joint_name));
            return j;
          };
          const std::string j = joint("joint"), l = joint("leader");
          con = joint_coupling(m, j, l, c.number(c.need(e, "ratio", kk), kk + ".ratio"),
                               e["offset"] ? c.number(e["offset"], kk + ".offset") : 0.0, origin);
        } else if (kind == "points_coincide") {
          c.keys(e, k, {"name", "origin", "kind", "points", "axes"});
          const YAML::Node ps = c.need(e, "points", kk);
          if (!ps.IsSequence() || ps.size() != 2) c.fail(ps, kk + ".points", "expected two point names [A, B]");
          std::vector<int> axes{0, 1, 2};
          if (e["axes"]) {
            axes.clear();
            for (size_t a = 0; a < e["axes"].size(); ++a) axes.push_back(axis_index(c, e["axes"][a], kk + ".axes"));
          }
          for (int a = 0; a < 2; ++a) {
            const std::string p = c.string(ps[a], kk + ".points");
            if (std::find(m.point_name.begin(), m.point_name.end(), p) == m.point_name.end())
              c.fail(ps[a], kk + ".points", "unknown point '" + p + "'" + did_you_mean(p, m.point_name));
          }
          con = points_coincide(m, ps[0].Scalar(), ps[1].Scalar(), axes, origin);
        } else if (kind == "knife_edge") {
          c.keys(e, k, {"name", "origin", "kind", "point", "lateral_axis"});
          con = knife_edge(m, point("point"), c.vec3(c.need(e, "lateral_axis", kk), kk + ".lateral_axis"), origin);
        } else {
          c.keys(e, k, {"name", "origin", "kind", "point", "direction", "speed"});
          con = point_speed(m, point("point"), c.vec3(c.need(e, "direction", kk), kk + ".direction"),
                            read_time_function(c, c.need(e, "speed", kk), kk + ".speed"), origin);
        }
        std::const_pointer_cast<Constraint>(con)->name = name;
      }
      out.add(con);
    } catch (const Error& err) {
      const std::string w = err.what();
      if (w.rfind(c.file(), 0) == 0) throw;
      c.fail(e, kk, w);
    }
  }
}

std::string substitute(std::string s, const std::string& var, double v) {
  const std::string pat = "{" + var + "}";
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  for (size_t pos; (pos = s.find(pat)) != std::string::npos;) s.replace(pos, pat.size(), b);
  return s;
}

}  // namespace

std::unique_ptr<Scenario> parse_scenario(const std::string& text, const std::string& source) {
  Ctx c(source);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    std::string hint;
    std::istringstream lines(text);
    std::string l;
    for (int k = 0; std::getline(lines, l); ++k) {
      const auto b = l.find_first_not_of(" \t");
      if (b != std::string::npos && l.substr(0, b).find('\t') != std::string::npos) {
        hint = " (line " + std::to_string(k + 1) + " is indented with a tab; YAML allows only spaces for indentation)";
        break;
      }
    }
    throw Error(source + (e.mark.is_null() ? "" : ":" + std::to_string(e.mark.line + 1)) +
                ": YAML syntax error: " + e.msg + hint);
  }
  if (!root.IsMap()) throw Error(source + ": expected a YAML mapping at the top level (keys such as model:, constraints:)");
  c.keys(root, "", {"name", "parameters", "model", "constraints", "partition", "forces", "baumgarte", "solver",
                    "paper_literal_forces", "initial", "integrator", "controller", "effort_limit", "plant_forces",
                    "experiments", "outputs"});
  auto s = std::make_unique<Scenario>();
  s->file = source;
  s->name = root["name"] ? c.string(root["name"], "name") : fs::path(source).stem().string();

  c.params["deg"] = std::numbers::pi / 180.0;
  if (const YAML::Node p = root["parameters"]) {
    if (!p.IsMap()) c.fail(p, "parameters", "expected a mapping name: value");
    for (const auto& kv : p) {
      const std::string name = kv.first.as<std::string>();
      c.params[name] = c.number(kv.second, "parameters." + name);
    }
  }
  s->parameters = c.params;

  std::map<std::string, int> link_lines;
  std::vector<UrdfMimic> mimics;
  s->description = read_model(c, c.need(root, "model", ""), link_lines, mimics);
  if (!root["model"]["name"]) s->description.name = s->name;
  try {
    s->model = build_model(s->description);
  } catch (const Error& e) {
    // Locate the link the message names, if any.
    const std::string w = e.what();
    for (const auto& [name, line] : link_lines)
      if (w.find("'" + name + "'") != std::string::npos)
        throw Error(source + ":" + std::to_string(line) + ": model: " + w);
    c.fail(root["model"], "model", w);
  }
  const Model& m = s->model;

  // URDF <mimic> joints: material couplings, before the file's own constraints.
  for (const UrdfMimic& mm : mimics) {
    try {
      ConstraintPtr con = joint_coupling(m, mm.joint, mm.leader, mm.multiplier, mm.offset, ConstraintOrigin::Material);
      std::const_pointer_cast<Constraint>(con)->name = "mimic_" + mm.joint;
      s->constraints.add(con);
    } catch (const Error& e) {
      c.fail(root["model"]["urdf"], "model.urdf", e.what());
    }
  }
  read_constraints(c, root["constraints"], m, s->constraints);
  read_forces(c, root["forces"], "forces", m, s->forces);

  if (const YAML::Node b = root["baumgarte"]) {
    c.keys(b, "baumgarte", {"alpha", "beta", "beta_first_order"});
    s->options.alpha = c.number_or(b, "alpha", "baumgarte", s->options.alpha);
    s->options.beta = c.number_or(b, "beta", "baumgarte", s->options.beta);
    s->options.beta_first_order = c.number_or(b, "beta_first_order", "baumgarte", s->options.beta_first_order);
    try {
      s->options.validate();
    } catch (const Error& e) {
      c.fail(b, "baumgarte", e.what());
    }
  }
  if (root["solver"])
    s->options.solver = c.choice(root["solver"], "solver", {"projection", "lagrange"}) == "projection"
                            ? ReferenceSolver::Projection : ReferenceSolver::Lagrange;
  if (root["paper_literal_forces"]) s->options.paper_literal_forces = c.boolean(root["paper_literal_forces"], "paper_literal_forces");

  const int nrows = s->constraints.rows();
  if (nrows > m.nq) c.fail(root["constraints"], "constraints", "expected at most " + std::to_string(m.nq) + " constraint rows (one per coordinate), got " + std::to_string(nrows));
  const YAML::Node part = root["partition"];
  if (!part || (part.IsScalar() && part.Scalar() == "auto")) {
    s->automatic_independent = true;
  } else {
    c.keys(part, "partition", {"independent", "automatic_switch", "max_condition"});
    const YAML::Node ind = c.need(part, "independent", "partition");
    if (ind.IsScalar() && ind.Scalar() == "auto") {
      s->automatic_independent = true;
    } else {
      if (!ind.IsSequence()) c.fail(ind, "partition.independent", "expected a list of joint names or 'auto', got " + Ctx::kind(ind));
      if (static_cast<int>(ind.size()) != m.nq - nrows)
        c.fail(ind, "partition.independent", "expected " + std::to_string(m.nq - nrows) + " independent coordinates (" +
                   std::to_string(m.nq) + " coordinates minus " + std::to_string(nrows) + " constraint rows), got " +
                   std::to_string(ind.size()) + " (joints: " + Ctx::joint_list(m) + ")");
      for (size_t i = 0; i < ind.size(); ++i) {
        const std::string j = c.string(ind[i], "partition.independent");
        if (std::find(m.joint_name.begin(), m.joint_name.end(), j) == m.joint_name.end())
          c.fail(ind[i], "partition.independent", "unknown joint '" + j + "'" + did_you_mean(j, m.joint_name));
        if (std::find(s->options.independent.begin(), s->options.independent.end(), j) != s->options.independent.end())
          c.fail(ind[i], "partition.independent", "joint '" + j + "' is listed twice");
        s->options.independent.push_back(j);
      }
    }
    if (part["automatic_switch"]) s->options.automatic_partition = c.boolean(part["automatic_switch"], "partition.automatic_switch");
    s->options.max_condition = c.number_or(part, "max_condition", "partition", s->options.max_condition);
    if (!(s->options.max_condition > 1)) c.fail(part["max_condition"], "partition.max_condition", "expected a value > 1");
  }

  const YAML::Node ini = c.need(root, "initial", "");
  c.keys(ini, "initial", {"q", "qd", "consistency", "tolerance"});
  s->q0 = c.joint_vector(c.need(ini, "q", "initial"), "initial.q", m, true, 0.0);
  s->qd0 = ini["qd"] ? c.joint_vector(ini["qd"], "initial.qd", m, false, 0.0) : Eigen::VectorXd::Zero(m.nq);
  if (ini["consistency"]) s->project_initial = c.choice(ini["consistency"], "initial.consistency", {"check", "project"}) == "project";
  s->initial_tolerance = c.number_or(ini, "tolerance", "initial", s->initial_tolerance);
  if (!(s->initial_tolerance > 0)) c.fail(ini["tolerance"], "initial.tolerance", "expected a value > 0");

  if (const YAML::Node in = root["integrator"]) {
    c.keys(in, "integrator", {"method", "step", "t0", "t1", "rtol", "atol", "output_interval", "min_step", "residual_from"});
    IntegratorOptions& o = s->integrator;
    if (in["method"]) o.method = c.choice(in["method"], "integrator.method", {"rk4", "dopri5"}) == "rk4" ? IntegratorMethod::RK4 : IntegratorMethod::DormandPrince45;
    o.step = c.number_or(in, "step", "integrator", o.step);
    o.t0 = c.number_or(in, "t0", "integrator", o.t0);
    o.t1 = c.number_or(in, "t1", "integrator", o.t1);
    o.rtol = c.number_or(in, "rtol", "integrator", o.rtol);
    o.atol = c.number_or(in, "atol", "integrator", o.atol);
    o.output_interval = c.number_or(in, "output_interval", "integrator", o.output_interval);
    o.min_step = c.number_or(in, "min_step", "integrator", std::min(o.min_step, 0.5 * o.step));
    s->residual_from = c.number_or(in, "residual_from", "integrator", 0.0);
    try {
      o.validate();
    } catch (const Error& e) {
      c.fail(in, "integrator", e.what());
    }
  }

  // Initial consistency and partition at t0 (with a temporary ReferenceDynamics).
  s->initial_dq = Eigen::VectorXd::Zero(m.nq);
  s->initial_dqd = Eigen::VectorXd::Zero(m.nq);
  {
    ReferenceDynamics rd(m, s->forces, s->constraints, s->options);
    const double t0 = s->integrator.t0;
    if (s->automatic_independent) {
      rd.choose_partition(t0, s->q0, s->qd0);
      s->options.independent.clear();
      for (int i : rd.independent()) s->options.independent.push_back(m.joint_name[i]);
    }
    if (s->project_initial) {
      const auto cons = rd.make_consistent(t0, s->q0, s->qd0, 1e-12);
      if (!cons.converged)
        c.fail(ini, "initial", "the Newton projection onto the constraints did not converge (residual " +
                                   fmt(cons.residual_after) + "); start closer to a consistent configuration");
      s->q0 = cons.q;
      s->qd0 = cons.qd;
      s->initial_dq = cons.dq;
      s->initial_dqd = cons.dqd;
    }
    Eigen::VectorXd x = rd.make_state(s->q0, s->qd0), dx(x.size());
    const double r = rd.residual(t0, x);
    const ConstraintEval& ev = rd.constraints();
    for (int row = 0; row < nrows; ++row) {
      const double v = std::max(std::abs(ev.phi[row]), std::abs(ev.phid[row]));
      if (v > s->initial_tolerance)
        c.fail(ini, "initial", "the initial state violates constraint '" + s->constraints.row_name(row) + "' by " + fmt(v) +
                                   " (|Phi| or |dPhi/dt|) > tolerance " + fmt(s->initial_tolerance) +
                                   " (hint: set initial.consistency: project, or correct q/qd)");
    }
    (void)r;
    if (s->options.solver == ReferenceSolver::Projection && nrows > 0) {
      try {
        rd.derivative(t0, x, dx);
      } catch (const NumericalFailure& e) {
        c.fail(part ? part : root, "partition", e.what());
      }
    }
  }

  // Tracking. Gains are numbers or expressions in the parameters (and, inside an experiment,
  // its sweep parameter).
  auto read_controller = [&](const YAML::Node& ct, const std::string& key, const std::map<std::string, double>* extra) {
    ControllerSpec cs;
    c.keys(ct, key, {"type", "delta", "kp", "kd"});
    cs.type = c.choice(c.need(ct, "type", key), key + ".type", {"computed_torque_pd", "pd_gravity"});
    auto gains = [&](const char* name) {
      const Eigen::VectorXd v = c.joint_vector(c.need(ct, name, key), key + "." + name, m, true, 0.0, extra);
      for (int i = 0; i < m.nq; ++i)
        if (!(v[i] >= 0))
          c.fail(ct[name], key + "." + name + "." + m.joint_name[i], "gains must be >= 0, got " + fmt(v[i]));
      return v;
    };
    if (cs.type == "computed_torque_pd") {
      cs.delta = gains("delta");
    } else {
      cs.kp = gains("kp");
      cs.kd = gains("kd");
    }
    return cs;
  };
  if (const YAML::Node ct = root["controller"]) s->controller = read_controller(ct, "controller", nullptr);
  if (root["effort_limit"]) {
    s->effort_limit = c.joint_vector(root["effort_limit"], "effort_limit", m, false, std::numeric_limits<double>::infinity());
    for (int i = 0; i < m.nq; ++i)
      if (!(s->effort_limit[i] >= 0))
        c.fail(root["effort_limit"], "effort_limit." + m.joint_name[i],
               "expected a limit >= 0 [N m or N], got " + fmt(s->effort_limit[i]));
  }
  if (const YAML::Node ex = root["experiments"]) {
    if (!ex.IsSequence()) c.fail(ex, "experiments", "expected a list of experiments");
    for (size_t i = 0; i < ex.size(); ++i) {
      const YAML::Node e = ex[i];
      const std::string k = "experiments[" + std::to_string(i) + "]";
      c.keys(e, k, {"name", "sweep", "initial", "plant_forces", "controller"});
      if (!root["controller"] && !e["controller"])
        c.fail(e, "controller",
               "experiments need a controller (add a 'controller:' section, at the top level or in the experiment)");
      std::string var;
      std::vector<double> values{0.0};
      if (const YAML::Node sw = e["sweep"]) {
        if (!sw.IsMap() || sw.size() != 1) c.fail(sw, k + ".sweep", "expected one entry  name: [values]");
        var = sw.begin()->first.as<std::string>();
        const YAML::Node vs = sw.begin()->second;
        if (!vs.IsSequence() || vs.size() == 0) c.fail(vs, k + ".sweep." + var, "expected a non-empty list of values");
        values.clear();
        for (size_t v = 0; v < vs.size(); ++v) values.push_back(c.number(vs[v], k + ".sweep." + var));
      }
      const std::string name_t = e["name"] ? c.string(e["name"], k + ".name") : "run" + std::to_string(i);
      for (double v : values) {
        std::map<std::string, double> extra;
        if (!var.empty()) extra[var] = v;
        auto exp = std::make_unique<Experiment>();
        exp->name = var.empty() ? name_t : substitute(name_t, var, v);
        for (const auto& other : s->experiments)
          if (other->name == exp->name) c.fail(e, k + ".name", "duplicate experiment name '" + exp->name + "' (use {" + (var.empty() ? "param" : var) + "} in the name)");
        exp->q0 = s->q0;
        exp->qd0 = Eigen::VectorXd::Zero(m.nq);
        if (const YAML::Node in = e["initial"]) {
          c.keys(in, k + ".initial", {"q", "qd"});
          if (in["q"]) {
            const Eigen::VectorXd given = c.joint_vector(in["q"], k + ".initial.q", m, false, std::nan(""), &extra);
            for (int j = 0; j < m.nq; ++j)
              if (!std::isnan(given[j])) exp->q0[j] = given[j];
          }
          if (in["qd"]) exp->qd0 = c.joint_vector(in["qd"], k + ".initial.qd", m, false, 0.0, &extra);
        }
        const YAML::Node pf = e["plant_forces"] ? e["plant_forces"] : root["plant_forces"];
        Ctx ce = c;  // the sweep parameter is visible in the run's plant forces too
        ce.params.insert(extra.begin(), extra.end());
        read_forces(ce, pf, e["plant_forces"] ? k + ".plant_forces" : "plant_forces", m, exp->plant_forces);
        exp->controller = e["controller"] ? read_controller(e["controller"], k + ".controller", &extra) : s->controller;
        s->experiments.push_back(std::move(exp));
      }
    }
  }
  if (const YAML::Node out = root["outputs"]) {
    c.keys(out, "outputs", {"points"});
    if (const YAML::Node ps = out["points"]) {
      if (!ps.IsSequence()) c.fail(ps, "outputs.points", "expected a list of point names");
      for (size_t i = 0; i < ps.size(); ++i) {
        const std::string p = c.string(ps[i], "outputs.points");
        if (std::find(m.point_name.begin(), m.point_name.end(), p) == m.point_name.end())
          c.fail(ps[i], "outputs.points", "unknown point '" + p + "'" + did_you_mean(p, m.point_name));
        s->report_points.push_back(p);
      }
    }
  } else {
    s->report_points = m.point_name;
  }
  return s;
}

std::unique_ptr<Scenario> load_scenario(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("scenario file '" + path + "': cannot be read: " + std::strerror(errno));
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_scenario(ss.str(), path);
}

}  // namespace refdyn::io
