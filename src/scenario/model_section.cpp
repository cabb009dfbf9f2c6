// build_problem, the model section: model: (links or dh, URDF, points) → Model and ModelNumbers.
#include "refdyn/scenario/problem.hpp"

#include "build.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/scenario/schema.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <random>
#include <map>
#include <set>

namespace refdyn::build {

namespace {

LinkInertia read_inertia(const SpecReader& c, const SpecValue& n, const std::string& key) {
  LinkInertia in;
  if (n["mass"]) in.mass = c.number(n["mass"], key + ".mass");
  if (in.mass < 0) c.fail(n["mass"], key + ".mass", "expected a number >= 0 [kg], got " + fmt(in.mass));
  if (n["com"]) in.com = c.vec3(n["com"], key + ".com");
  if (const SpecValue& I = n["inertia"]) {
    const std::string k = key + ".inertia";
    if (!I.is_list()) c.fail(I, k, "expected [Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] or a 3x3 list, got " + I.describe());
    if (I.size() == 3 && I[0].is_list()) {
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
  // Each number may be finite while the spatial inertia they make is not (mass 1e300 at a COM
  // of 1e200: m |c|^2 overflows); name the key whose value overflows, not a singular M later.
  const double r = in.com.stableNorm(), mr = in.mass * r, mrr = mr * r;
  if (!std::isfinite(mr) || !std::isfinite(mrr)) {
    const bool at_com = n["com"] && r > 1;
    c.fail(at_com ? n["com"] : n["mass"], key + (at_com ? ".com" : ".mass"),
           "mass " + fmt(in.mass) + " kg with its centre of mass at distance " + fmt(r) +
               " m overflows: the inertia about the joint, m |com|^2 = " + fmt(mrr) +
               ", is not a finite number (check the units of mass and com)");
  }
  return in;
}

JointLimits read_limits(const SpecReader& c, const SpecValue& n, const std::string& key) {
  JointLimits l;
  if (!n) return l;
  c.keys(n, key, schema::keys("model.dh.joints[].limits"));
  l.lower = c.number_or(n, "lower", key, l.lower);
  l.upper = c.number_or(n, "upper", key, l.upper);
  l.velocity = c.number_or(n, "velocity", key, l.velocity);
  l.effort = c.number_or(n, "effort", key, l.effort);
  return l;
}

/// A joint's armature [kg m² or kg]: a number >= 0 (an expression of the parameters).
double read_armature(const SpecReader& c, const SpecValue& n, const std::string& key) {
  const double a = c.number(n, key);
  if (!(a >= 0) || !std::isfinite(a))
    c.fail(n, key, "expected a finite armature >= 0 (the rotor inertia reflected to the joint, I_r N^2 [kg m^2]; kg for "
                   "a prismatic joint), got " + fmt(a));
  return a;
}

JointType read_joint_type(const SpecReader& c, const SpecValue& n, const std::string& key) {
  const std::string t = c.choice(n, key, schema::choices("model.links[]", "type"));
  return t == "revolute" ? JointType::Revolute : t == "prismatic" ? JointType::Prismatic : JointType::Fixed;
}

/// The numbers of a model node (already checked by read_model) as Quantities.
struct ModelNumberReader {
  const SpecReader& c;
  ModelNumbers::Vec vec(const SpecValue& n, const std::string& k) const {
    return {c.quantity(n[0], k + "[0]"), c.quantity(n[1], k + "[1]"), c.quantity(n[2], k + "[2]")};
  }
  std::optional<Quantity> opt(const SpecValue& parent, const char* f, const std::string& k) const {
    if (!parent[f]) return std::nullopt;
    return c.quantity(parent[f], k + "." + f);
  }
  std::optional<ModelNumbers::Vec> opt_vec(const SpecValue& parent, const char* f, const std::string& k) const {
    if (!parent[f]) return std::nullopt;
    return vec(parent[f], k + "." + f);
  }
  ModelNumbers::Pose pose(const SpecValue& n, const std::string& k) const {
    return {opt_vec(n, "xyz", k), opt_vec(n, "rpy", k)};
  }
  /// mass, com and inertia of a link.
  void inertia(const SpecValue& l, const std::string& k, ModelNumbers::Link& out) const {
    out.mass = opt(l, "mass", k);
    out.com = opt_vec(l, "com", k);
    if (const SpecValue& I = l["inertia"]) {
      const std::string ik = k + ".inertia";
      out.inertia_matrix = I.size() == 3 && I[0].is_list();
      if (out.inertia_matrix) {
        for (int r = 0; r < 3; ++r)
          for (const Quantity& x : vec(I[r], ik + "[" + std::to_string(r) + "]")) out.inertia.push_back(x);
      } else {
        for (size_t i = 0; i < I.size(); ++i) out.inertia.push_back(c.quantity(I[i], ik + "[" + std::to_string(i) + "]"));
      }
    }
  }
};

/// model.points: name: {link, position}; a name that a URDF link's point already has is refused.
void read_points(const SpecReader& c, const ModelNumberReader& nr, const SpecValue& ps, ModelDescription& d,
                 std::optional<ModelNumbers>& numbers) {
  if (!ps.is_map()) c.fail(ps, "model.points", "expected a mapping name: {link: ..., position: [x, y, z]}");
  for (const auto& kv : ps.entries) {
    const std::string& name = kv.key;
    const std::string k = "model.points." + name;
    c.keys(kv.value, k, schema::keys("model.points.<name>"));
    const std::string link = c.string(c.need(kv.value, "link", k), k + ".link");
    Vec3 pos = Vec3::Zero();
    if (kv.value["position"]) pos = c.vec3(kv.value["position"], k + ".position");
    bool known = link == "world" || link == "base";
    std::vector<std::string> names;
    for (const auto& l : d.links) {
      names.push_back(l.name);
      known = known || l.name == link;
    }
    if (!known) c.fail(kv.value["link"], k + ".link", "unknown link '" + link + "'" + did_you_mean(link, names));
    // The points that exist before model.points are the URDF's, one per link frame origin: a
    // point of the same name would silently move what x(NAME) means (and every constraint on it).
    for (const PointSpec& existing : d.points)
      if (existing.name == name)
        c.fail(ps.key_location(name), k,
               "a point named '" + name + "' already exists: refdyn gives every URDF link a point at its frame origin, "
               "and this one would replace the origin of link '" + existing.link +
                   "' (hint: rename this point, e.g. '" + name + "_point'; x(" + name + ") keeps the link's origin)");
    d.add_point(name, link, pos);
    if (numbers) numbers->points.push_back({name, link, nr.opt_vec(kv.value, "position", k)});
  }
}

/// model.armature: {joint: value}: a joint's armature for any model. For a URDF it replaces the
/// value of the Drake tags; a joint of a links:/dh: model may not have it twice.
void read_armature_map(const SpecReader& c, const ModelNumberReader& nr, const SpecValue& am, ModelDescription& d,
                       std::optional<ModelNumbers>& numbers, std::vector<std::string>& notes) {
  if (!am.is_map()) c.fail(am, "model.armature", "expected a mapping joint: armature, got " + am.describe());
  for (const auto& kv : am.entries) {
    const std::string k = "model.armature." + kv.key;
    std::vector<std::string> names;
    int found = -1;
    for (size_t i = 0; i < d.links.size(); ++i)
      if (d.links[i].type != JointType::Fixed) {
        const std::string& jn = d.links[i].joint_name.empty() ? d.links[i].name : d.links[i].joint_name;
        names.push_back(jn);
        if (jn == kv.key) found = static_cast<int>(i);
      }
    if (found < 0) c.fail(am.key_location(kv.key), k, "unknown joint '" + kv.key + "' (a joint that moves)" + did_you_mean(kv.key, names));
    if (numbers && numbers->links[found].armature)
      c.fail(am.key_location(kv.key), k, "joint '" + kv.key + "' already has an armature in its model entry (hint: give it once)");
    const double before = d.links[found].armature;
    d.links[found].armature = read_armature(c, kv.value, k);
    if (!numbers && before != 0)
      notes.push_back("joint " + kv.key + ": armature " + fmt(d.links[found].armature) + " from model.armature (replaces the URDF's " +
                      fmt(before) + ")");
    if (numbers) numbers->links[found].armature = nr.c.quantity(kv.value, k);
  }
}

ModelDescription read_model(const SpecReader& c, const SpecValue& m, const std::optional<ModelDescription>& urdf,
                            std::map<std::string, int>& link_lines, std::optional<ModelNumbers>& numbers,
                            std::vector<std::string>& notes) {
  const ModelNumberReader nr{c};
  const std::string key = "model";
  c.keys(m, key, schema::keys("model"));
  const int sources = (m["dh"] ? 1 : 0) + (m["links"] ? 1 : 0) + (m["urdf"] ? 1 : 0);
  if (sources != 1) c.fail(m, key, "expected exactly one of 'dh', 'links' or 'urdf', got " + std::to_string(sources));
  ModelDescription d;
  if (const SpecValue& dh = m["dh"]) {
    c.keys(dh, "model.dh", schema::keys("model.dh"));
    DHConvention conv = DHConvention::Standard;
    if (dh["convention"]) conv = c.choice(dh["convention"], "model.dh.convention", schema::choices("model.dh", "convention")) == "standard"
                                     ? DHConvention::Standard : DHConvention::Modified;
    const SpecValue& js = c.need(dh, "joints", "model.dh");
    if (!js.is_list() || js.size() == 0) c.fail(js, "model.dh.joints", "expected a non-empty list of joints");
    std::vector<DHRow> rows;
    std::vector<std::string> link_names;
    numbers.emplace();
    numbers->dh = true;
    numbers->standard = conv == DHConvention::Standard;
    for (size_t i = 0; i < js.size(); ++i) {
      const SpecValue& j = js[i];
      const std::string k = "model.dh.joints[" + std::to_string(i) + "]";
      c.keys(j, k, schema::keys("model.dh.joints[]"));
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
      ModelNumbers::Link L;
      L.name = link_names.back();
      L.parent = static_cast<int>(i) - 1;
      L.type = r.type;
      L.theta = nr.opt(j, "theta", k);
      L.d = nr.opt(j, "d", k);
      L.a = nr.opt(j, "a", k);
      L.alpha = nr.opt(j, "alpha", k);
      L.armature = nr.opt(j, "armature", k);
      nr.inertia(j, k, L);
      numbers->links.push_back(std::move(L));
      link_lines[link_names.back()] = j.where.line;
    }
    d = from_dh(rows, conv);
    for (size_t i = 0; i < rows.size(); ++i) {
      d.links[i].name = link_names[i];
      d.links[i].joint_name = rows[i].name;
      const std::string k = "model.dh.joints[" + std::to_string(i) + "]";
      if (js[i]["armature"]) d.links[i].armature = read_armature(c, js[i]["armature"], k + ".armature");
    }
  } else if (const SpecValue& ls = m["links"]) {
    if (!ls.is_list() || ls.size() == 0) c.fail(ls, "model.links", "expected a non-empty list of links");
    std::map<std::string, int> index;
    numbers.emplace();
    for (size_t i = 0; i < ls.size(); ++i) {
      const SpecValue& l = ls[i];
      const std::string k = "model.links[" + std::to_string(i) + "]";
      c.keys(l, k, schema::keys("model.links[]"));
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
      if (l["armature"]) s.armature = read_armature(c, l["armature"], k + ".armature");
      ModelNumbers::Link L;
      L.name = s.name;
      L.parent = s.parent;
      L.type = s.type;
      L.origin = l["origin"] ? nr.pose(l["origin"], k + ".origin") : ModelNumbers::Pose{};
      L.link_offset = l["link_offset"] ? nr.pose(l["link_offset"], k + ".link_offset") : ModelNumbers::Pose{};
      L.offset = nr.opt(l, "offset", k);
      L.armature = nr.opt(l, "armature", k);
      nr.inertia(l, k, L);
      numbers->links.push_back(std::move(L));
      index[s.name] = static_cast<int>(d.links.size());
      link_lines[s.name] = l.where.line;
      d.add_link(s);
    }
  } else {
    if (!urdf) c.fail(m["urdf"], "model.urdf", "the URDF file was not loaded (hint: load the scenario with io::load_scenario)");
    d = *urdf;
  }
  if (m["name"]) d.name = c.string(m["name"], "model.name");
  if (m["gravity"]) d.gravity = c.vec3(m["gravity"], "model.gravity");
  if (m["base"]) d.base = c.pose(m["base"], "model.base");
  if (numbers && m["base"]) numbers->base = nr.pose(m["base"], "model.base");
  if (const SpecValue& ps = m["points"]) read_points(c, nr, ps, d, numbers);
  if (const SpecValue& a = m["armature"]) read_armature_map(c, nr, a, d, numbers, notes);
  return d;
}

}  // namespace

/// model: the Problem with its model, names and parameters (every name checked).
std::unique_ptr<Problem> build_model_section(const SpecReader& c, const ScenarioSpec& spec) {
  const std::string& source = spec.file;
  std::map<std::string, int> link_lines;
  std::optional<ModelNumbers> numbers;
  std::vector<std::string> notes = spec.model.notes;
  ModelDescription description = read_model(c, spec.model.value, spec.model.urdf, link_lines, numbers, notes);
  if (!spec.model.value["name"]) description.name = spec.name;
  std::unique_ptr<Problem> s;
  try {
    s = std::make_unique<Problem>(build_model(description));
  } catch (const Error& e) {
    // Locate the link the message names, if any.
    const std::string w = e.what();
    for (const auto& [name, line] : link_lines)
      if (w.find("'" + name + "'") != std::string::npos) c.fail(SourceLocation{source, line}, "model", w);
    c.fail(spec.model.value, "model", w);
  }
  s->file = source;
  s->name = spec.name;
  check_name(c, spec.root["name"] ? spec.root["name"] : spec.root, "name", spec.name);
  {
    const Model& mm = s->model;
    for (const auto* names : {&mm.joint_name, &mm.body_name, &mm.point_name})
      for (const auto& nm : *names) {
        const auto it = link_lines.find(nm);
        check_name(c, it != link_lines.end() ? SpecValue::scalar(nm, {source, it->second}) : spec.model.value, "model", nm);
      }
    std::set<std::string> joints;
    for (const auto& j : mm.joint_name)
      if (!joints.insert(j).second) {
        const auto it = link_lines.find(j);
        c.fail(it != link_lines.end() ? SpecValue::scalar(j, {source, it->second}) : spec.model.value, "model",
               "two joints are named '" + j + "' (joint names must be unique: they name columns, gains and constraints)");
      }
  }
  s->parameters = c.params;
  s->model_numbers = std::move(numbers);
  s->model_notes = std::move(notes);
  s->visuals = description.visuals;
  const Model& m = s->model;
  if (m.nv == 0)
    c.fail(spec.model.value, "model",
           "the model has no moving joint: nothing to plan (every joint is 'fixed'; give at least one the type "
           "revolute or prismatic)");
  return s;
}

}  // namespace refdyn::build
