#include "refdyn/io/urdf.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <boost/property_tree/detail/rapidxml.hpp>
#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

namespace refdyn::io {

namespace {

namespace rapidxml_ns = boost::property_tree::detail::rapidxml;

std::string where(const std::string& source) { return "URDF file '" + source + "': "; }

/// A xacro file (macros, properties, includes) is not a URDF: urdfdom would read what it can of
/// it (or nothing: "No name given for the robot"). Recognised by its name (.xacro) or by a
/// <xacro:...> element; a stray xmlns:xacro declaration alone, which expanded files may keep, is
/// not enough.
void refuse_xacro(const std::string& xml, const std::string& source) {
  const bool named = source.size() >= 6 && source.compare(source.size() - 6, 6, ".xacro") == 0;
  if (!named && xml.find("<xacro:") == std::string::npos) return;
  std::string out = named ? source.substr(0, source.size() - 6) : source;
  if (out.size() < 5 || out.compare(out.size() - 5, 5, ".urdf") != 0) out += ".urdf";
  if (out == source) out = source + ".urdf";  // an unnamed xacro file called x.urdf: x.urdf.urdf
  throw Error(where(source) + "this is a xacro file (" +
              (named ? std::string("its name ends in .xacro") : std::string("it has <xacro:...> elements")) +
              "), not a URDF: expand it first with `xacro " + source + " > " + out +
              "` (ROS's xacro package) and load " + out);
}

// --- urdfdom diagnostics --------------------------------------------------------------------
// urdfdom reports problems through console_bridge (printed to stderr by default) and returns
// a null model. While we parse, a handler collects the error messages of this thread, so that
// they can be quoted in the one-line refdyn::Error; everything else goes to the handler that
// was installed before. The handler is never destroyed: console_bridge keeps a raw pointer to
// the "previous" handler, which restorePreviousOutputHandler() may reinstate later.

class CaptureHandler final : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* filename,
           int line) override {
    // console_bridge serializes calls to the current handler with its own lock.
    if (capturing_ && std::this_thread::get_id() == thread_ && level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) {
      errors_.push_back(text);
      return;
    }
    console_bridge::OutputHandler* forward = forward_.load();
    if (forward && level >= forward_level_.load()) forward->log(text, level, filename, line);
  }
  void begin(console_bridge::OutputHandler* forward, console_bridge::LogLevel forward_level) {
    if (forward != this) forward_ = forward;  // else keep forwarding where we did before
    forward_level_ = forward_level;
    errors_.clear();
    thread_ = std::this_thread::get_id();
    capturing_ = true;
  }
  std::vector<std::string> end() {
    capturing_ = false;
    return std::move(errors_);
  }

 private:
  std::atomic<console_bridge::OutputHandler*> forward_{nullptr};
  std::atomic<console_bridge::LogLevel> forward_level_{console_bridge::CONSOLE_BRIDGE_LOG_WARN};
  std::thread::id thread_;
  std::atomic<bool> capturing_{false};
  std::vector<std::string> errors_;
};

struct ParseResult {
  urdf::ModelInterfaceSharedPtr model;
  std::vector<std::string> errors;  // urdfdom's error messages, in order
};

ParseResult parse_capturing(const std::string& xml) {
  static std::mutex mutex;
  static CaptureHandler* handler = new CaptureHandler;  // intentionally never deleted
  std::lock_guard<std::mutex> lock(mutex);

  console_bridge::OutputHandler* previous = console_bridge::getOutputHandler();
  const console_bridge::LogLevel level = console_bridge::getLogLevel();
  handler->begin(previous, level);
  // Errors must reach the handler even if the application silenced console_bridge.
  console_bridge::setLogLevel(std::min(level, console_bridge::CONSOLE_BRIDGE_LOG_ERROR));
  console_bridge::useOutputHandler(handler);
  struct Restore {
    console_bridge::OutputHandler* previous;
    console_bridge::LogLevel level;
    ~Restore() {
      console_bridge::useOutputHandler(previous);
      console_bridge::setLogLevel(level);
    }
  };

  ParseResult r;
  {
    Restore restore{previous, level};
    try {
      r.model = urdf::parseURDF(xml);
    } catch (const std::exception& e) {  // urdfdom mostly logs, but some versions throw
      r.model.reset();
      handler->log(e.what(), console_bridge::CONSOLE_BRIDGE_LOG_ERROR, __FILE__, __LINE__);
    }
  }
  r.errors = handler->end();
  return r;
}

std::string join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string s;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (i) s += sep;
    s += parts[i];
  }
  return s;
}

/// Message text on one line, without trailing periods (they are joined with "; ").
std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  while (!s.empty() && (s.back() == ' ' || s.back() == '.')) s.pop_back();
  return s;
}

/// Where malformed XML breaks, as "line L, column C: what" (empty if the XML is well formed).
/// urdfdom's TinyXML does not say where; Boost's rapidxml, checking closing tags, does.
std::string locate_xml_error(const std::string& xml) {
  namespace rx = boost::property_tree::detail::rapidxml;
  std::vector<char> buf(xml.begin(), xml.end());
  buf.push_back('\0');
  try {
    rx::xml_document<char> doc;
    doc.parse<rx::parse_validate_closing_tags>(buf.data());
  } catch (const rx::parse_error& e) {
    const char* at = e.where<char>();
    if (at < buf.data() || at > buf.data() + buf.size()) at = buf.data();
    const char* line_start = buf.data();
    int line = 1;
    for (const char* c = buf.data(); c < at; ++c)
      if (*c == '\n') {
        ++line;
        line_start = c + 1;
      }
    return "line " + std::to_string(line) + ", column " + std::to_string(at - line_start + 1) + ": " + e.what();
  } catch (const std::exception&) {
  }
  return {};
}

[[noreturn]] void throw_parse_failure(const std::string& xml, const std::string& source,
                                      std::vector<std::string> errors) {
  if (xml.find_first_not_of(" \t\r\n") == std::string::npos)
    throw Error(where(source) + "is empty (hint: a URDF starts with <robot name=\"...\">)");
  for (auto& e : errors) e = one_line(e);
  const std::string urdfdom = errors.empty() ? std::string() : join(errors, "; ");
  const std::string xml_error = locate_xml_error(xml);
  if (!xml_error.empty())
    throw Error(where(source) + "not well-formed XML at " + one_line(xml_error) +
                (urdfdom.empty() ? "" : " (urdfdom: " + urdfdom + ")") +
                " (hint: check the tags at and before that place; an element left open shows up at a later"
                " closing tag)");
  throw Error(where(source) + "not a valid URDF" + (urdfdom.empty() ? "" : ": " + urdfdom) +
              " (hint: the messages are urdfdom's; fix the element they name)");
}

// --- conversion ------------------------------------------------------------------------------

Mat3 rotation(const urdf::Rotation& r) {
  return Eigen::Quaterniond(r.w, r.x, r.y, r.z).normalized().toRotationMatrix();
}

SE3 pose(const urdf::Pose& p) {
  SE3 X;
  X.R = rotation(p.rotation);
  X.p = Vec3(p.position.x, p.position.y, p.position.z);
  return X;
}

LinkInertia inertia(const urdf::Link& link) {
  LinkInertia in;
  if (!link.inertial) return in;
  const urdf::Inertial& u = *link.inertial;
  Mat3 I;
  I << u.ixx, u.ixy, u.ixz,  //
      u.ixy, u.iyy, u.iyz,   //
      u.ixz, u.iyz, u.izz;
  const Mat3 R = rotation(u.origin.rotation);
  in.mass = u.mass;
  in.com = Vec3(u.origin.position.x, u.origin.position.y, u.origin.position.z);
  in.I_com = R * I * R.transpose();
  in.I_com = 0.5 * (in.I_com + in.I_com.transpose());  // exactly symmetric
  return in;
}

/// "Natural" order: digit runs compare as numbers, so "j2" < "j10".
bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const bool da = std::isdigit(static_cast<unsigned char>(a[i])) != 0;
    const bool db = std::isdigit(static_cast<unsigned char>(b[j])) != 0;
    if (da && db) {
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      size_t is = i, js = j;  // skip leading zeros
      while (is + 1 < ie && a[is] == '0') ++is;
      while (js + 1 < je && b[js] == '0') ++js;
      const std::string_view na(a.data() + is, ie - is), nb(b.data() + js, je - js);
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  if ((a.size() - i) != (b.size() - j)) return (a.size() - i) < (b.size() - j);
  return a < b;  // tie-break ("j01" vs "j1")
}

const char* urdf_type_name(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE: return "revolute";
    case urdf::Joint::CONTINUOUS: return "continuous";
    case urdf::Joint::PRISMATIC: return "prismatic";
    case urdf::Joint::FLOATING: return "floating";
    case urdf::Joint::PLANAR: return "planar";
    case urdf::Joint::FIXED: return "fixed";
    default: return "unknown";
  }
}

LinkSpec convert_joint(const urdf::Joint& j, const std::string& source, const UrdfOptions& opt,
                       std::vector<UrdfMimic>* mimics) {
  const std::string jw = where(source) + "joint '" + j.name + "'";
  if (j.mimic) {
    if (!mimics)
      throw Error(jw + " mimics joint '" + j.mimic->joint_name +
                  "': this loader was not asked for mimic couplings (hint: pass a std::vector<UrdfMimic>* to "
                  "load_urdf and add joint_coupling constraints, as scenario files do; or remove the <mimic> element)");
    if (j.type == urdf::Joint::FIXED)
      throw Error(jw + " is fixed and mimics joint '" + j.mimic->joint_name + "' (hint: remove the <mimic> element)");
    if (!std::isfinite(j.mimic->multiplier) || !std::isfinite(j.mimic->offset))
      throw Error(jw + ": <mimic> multiplier and offset must be finite numbers");
    mimics->push_back({j.name, j.mimic->joint_name, j.mimic->multiplier, j.mimic->offset});
  }
  LinkSpec l;
  l.name = j.child_link_name;
  l.joint_name = j.name;
  l.placement = pose(j.parent_to_joint_origin_transform);
  l.link_offset = SE3::Identity();
  switch (j.type) {
    case urdf::Joint::REVOLUTE:
    case urdf::Joint::CONTINUOUS: l.type = JointType::Revolute; break;
    case urdf::Joint::PRISMATIC: l.type = JointType::Prismatic; break;
    case urdf::Joint::FIXED: l.type = JointType::Fixed; break;
    case urdf::Joint::FLOATING:
      throw Error(jw + " is floating: floating joints are not supported, refdyn models have a fixed base "
                  "and 1-DOF joints (hint: to weld link '" + j.child_link_name + "' to the world, set " +
                  opt.root_link_option + " to '" + j.child_link_name +
                  "'; for a mobile base use prismatic and revolute joints)");
    case urdf::Joint::PLANAR:
      throw Error(jw + " is planar: planar joints are not supported (hint: replace it by two prismatic "
                  "joints and a revolute joint through massless intermediate links)");
    default:
      throw Error(jw + " has an unknown type (hint: use revolute, continuous, prismatic or fixed)");
  }
  if (l.type != JointType::Fixed) {
    const Vec3 axis(j.axis.x, j.axis.y, j.axis.z);
    if (!axis.allFinite() || axis.norm() < 1e-12)
      throw Error(jw + ": the " + urdf_type_name(j.type) + " joint axis is zero or not finite (hint: give a "
                  "non-zero axis in the joint frame, e.g. <axis xyz=\"0 0 1\"/>)");
    l.axis = axis.normalized();
    if (j.limits) {
      if (j.type != urdf::Joint::CONTINUOUS) {
        l.limits.lower = j.limits->lower;
        l.limits.upper = j.limits->upper;
      }
      l.limits.velocity = j.limits->velocity;
      l.limits.effort = j.limits->effort;
    }
  }
  return l;
}

void walk(const urdf::ModelInterface& u, const urdf::Link& link, int index, const std::string& source,
          const UrdfOptions& opt, ModelDescription& d, std::vector<UrdfMimic>* mimics,
          std::vector<UrdfJointDynamics>* dynamics) {
  std::vector<const urdf::Joint*> children;
  for (const auto& j : link.child_joints) children.push_back(j.get());
  std::sort(children.begin(), children.end(),
            [](const urdf::Joint* a, const urdf::Joint* b) { return natural_less(a->name, b->name); });
  for (const urdf::Joint* j : children) {
    urdf::LinkConstSharedPtr child = u.getLink(j->child_link_name);
    if (!child)  // urdfdom checks this; keep the walk safe anyway
      throw Error(where(source) + "joint '" + j->name + "': unknown child link '" + j->child_link_name + "'");
    LinkSpec l = convert_joint(*j, source, opt, mimics);
    l.parent = index;
    l.inertia = inertia(*child);
    if (dynamics && j->dynamics && l.type != JointType::Fixed) {
      const urdf::JointDynamics& dj = *j->dynamics;
      if (!std::isfinite(dj.damping) || !std::isfinite(dj.friction) || dj.damping < 0 || dj.friction < 0)
        throw Error(where(source) + "joint '" + j->name + "': <dynamics> damping and friction must be finite numbers >= 0");
      if (dj.damping != 0 || dj.friction != 0) dynamics->push_back({j->name, dj.damping, dj.friction});
    }
    const int ci = d.add_link(l);
    walk(u, *child, ci, source, opt, d, mimics, dynamics);
  }
}

// --- Drake's rotor tags ---------------------------------------------------------------------

double attribute_number(const rapidxml_ns::xml_node<char>& n, const std::string& what) {
  const auto* a = n.first_attribute("value");
  if (!a) throw Error(what + " has no value attribute (hint: <" + std::string(n.name(), n.name_size()) + " value=\"...\"/>)");
  const std::string text(a->value(), a->value_size());
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || !end || *end != 0 || !std::isfinite(v))
    throw Error(what + ": expected a finite number, got '" + text + "'");
  return v;
}

/// <transmission><joint name/><actuator><drake:rotor_inertia value/><drake:gear_ratio value/>:
/// armature I_r N² for joints of d (joints outside the loaded subtree are skipped).
void read_rotors(const std::string& xml, const std::string& source, const urdf::ModelInterface& u, ModelDescription& d,
                 std::vector<UrdfRotor>& rotors) {
  if (xml.find("drake:rotor_inertia") == std::string::npos && xml.find("drake:gear_ratio") == std::string::npos) return;
  std::vector<char> buf(xml.begin(), xml.end());
  buf.push_back('\0');
  rapidxml_ns::xml_document<char> doc;
  doc.parse<0>(buf.data());  // urdfdom has read it: well formed
  const auto* robot = doc.first_node("robot");
  if (!robot) return;
  for (const auto* t = robot->first_node("transmission"); t; t = t->next_sibling("transmission")) {
    const auto* act = t->first_node("actuator");
    const auto* ri = act ? act->first_node("drake:rotor_inertia") : nullptr;
    const auto* gr = act ? act->first_node("drake:gear_ratio") : nullptr;
    if (!ri && !gr) continue;
    const auto* tn = t->first_attribute("name");
    const std::string tw = where(source) + "transmission '" + (tn ? std::string(tn->value(), tn->value_size()) : "") + "'";
    const auto* jn = t->first_node("joint");
    const auto* ja = jn ? jn->first_attribute("name") : nullptr;
    if (!ja) throw Error(tw + ": Drake rotor tags need the transmission's <joint name=\"...\"> (hint: name the joint they drive)");
    const std::string joint(ja->value(), ja->value_size());
    if (!u.getJoint(joint))
      throw Error(tw + ": unknown joint '" + joint + "'");
    UrdfRotor r;
    r.joint = joint;
    if (ri) r.rotor_inertia = attribute_number(*ri, tw + " <drake:rotor_inertia>");
    if (gr) r.gear_ratio = attribute_number(*gr, tw + " <drake:gear_ratio>");
    if (r.rotor_inertia < 0) throw Error(tw + " <drake:rotor_inertia>: expected a value >= 0 [kg m^2], got " + fmt(r.rotor_inertia));
    const auto it = std::find_if(d.links.begin(), d.links.end(), [&](const LinkSpec& l) { return l.joint_name == joint; });
    if (it == d.links.end()) continue;  // outside the loaded subtree
    if (it->type == JointType::Fixed) throw Error(tw + ": joint '" + joint + "' is fixed: it has no rotor (hint: remove the Drake tags)");
    for (const UrdfRotor& o : rotors)
      if (o.joint == joint) throw Error(tw + ": joint '" + joint + "' has Drake rotor tags in two transmissions (hint: keep one)");
    it->armature = r.armature();
    rotors.push_back(r);
  }
  // in the model's joint order
  std::vector<UrdfRotor> ordered;
  for (const LinkSpec& l : d.links)
    for (const UrdfRotor& r : rotors)
      if (r.joint == l.joint_name) ordered.push_back(r);
  rotors = std::move(ordered);
}

// --- visuals ---------------------------------------------------------------------------------

namespace fs = std::filesystem;

/// The file a mesh URI names (UrdfOptions::packages), or "" with `note` saying why not.
std::string resolve_mesh(const std::string& uri, const std::string& source, const UrdfOptions& opt, std::string& note) {
  const std::string pkg = "package://", file = "file://";
  std::error_code ec;
  if (uri.compare(0, pkg.size(), pkg) == 0) {
    const std::string rest = uri.substr(pkg.size());
    const size_t slash = rest.find('/');
    const std::string name = rest.substr(0, slash), path = slash == std::string::npos ? "" : rest.substr(slash + 1);
    const auto it = opt.packages.find(name);
    if (it != opt.packages.end()) return (fs::path(it->second) / path).string();
    if (const char* rpp = std::getenv("ROS_PACKAGE_PATH")) {
      std::string entries = rpp;
      for (size_t from = 0; from <= entries.size();) {
        const size_t to = std::min(entries.find(':', from), entries.size());
        const fs::path e = entries.substr(from, to - from);
        from = to + 1;
        if (e.empty()) continue;
        if (fs::is_directory(e / name, ec)) return (e / name / path).string();
        if (e.filename() == name && fs::is_directory(e, ec)) return (e / path).string();
      }
    }
    note = "package '" + name + "' is not known (hint: model.urdf.packages: {" + name + ": FOLDER}, or ROS_PACKAGE_PATH)";
    return "";
  }
  std::string p = uri;
  if (uri.compare(0, file.size(), file) == 0) p = uri.substr(file.size());
  else if (uri.find("://") != std::string::npos) {
    note = "the URI scheme of '" + uri + "' is not supported (package://, file:// or a path)";
    return "";
  }
  if (p.empty()) {
    note = "empty mesh file name";
    return "";
  }
  const fs::path fp(p);
  return (fp.is_relative() ? fs::path(source).parent_path() / fp : fp).lexically_normal().string();
}

void read_visuals(const urdf::ModelInterface& u, const std::string& source, const UrdfOptions& opt, ModelDescription& d) {
  for (const LinkSpec& l : d.links) {
    const urdf::LinkConstSharedPtr link = u.getLink(l.name);
    if (!link) continue;
    for (const urdf::VisualSharedPtr& v : link->visual_array) {
      if (!v || !v->geometry) continue;
      VisualSpec s;
      s.link = l.name;
      s.origin = pose(v->origin);
      const urdf::Geometry& g = *v->geometry;
      switch (g.type) {
        case urdf::Geometry::MESH: {
          const auto& m = static_cast<const urdf::Mesh&>(g);
          s.shape = VisualSpec::Shape::Mesh;
          s.size = Vec3(m.scale.x, m.scale.y, m.scale.z);
          s.uri = m.filename;
          s.file = resolve_mesh(m.filename, source, opt, s.note);
          break;
        }
        case urdf::Geometry::BOX: {
          const auto& b = static_cast<const urdf::Box&>(g);
          s.shape = VisualSpec::Shape::Box;
          s.size = Vec3(b.dim.x, b.dim.y, b.dim.z);
          break;
        }
        case urdf::Geometry::CYLINDER: {
          const auto& c = static_cast<const urdf::Cylinder&>(g);
          s.shape = VisualSpec::Shape::Cylinder;
          s.radius = c.radius;
          s.length = c.length;
          break;
        }
        case urdf::Geometry::SPHERE:
          s.shape = VisualSpec::Shape::Sphere;
          s.radius = static_cast<const urdf::Sphere&>(g).radius;
          break;
        default: continue;
      }
      if (!s.size.allFinite() || !std::isfinite(s.radius) || !std::isfinite(s.length)) continue;  // nothing to draw
      if (v->material) {
        const urdf::Color& c = v->material->color;
        s.has_color = true;
        s.rgba = {c.r, c.g, c.b, c.a};
      }
      d.visuals.push_back(std::move(s));
    }
  }
}

ModelDescription parse(const std::string& xml, const std::string& source_name, const UrdfOptions& opt,
                       std::vector<UrdfMimic>* mimics, UrdfExtras* extras) {
  if (mimics) mimics->clear();
  refuse_xacro(xml, source_name);
  ParseResult parsed = parse_capturing(xml);
  // urdfdom sometimes logs an error and still returns a model (e.g. an <inertial> without
  // <inertia> yields a point mass); for dynamics every reported error is fatal.
  if (!parsed.model || !parsed.errors.empty()) throw_parse_failure(xml, source_name, std::move(parsed.errors));
  const urdf::ModelInterface& u = *parsed.model;

  urdf::LinkConstSharedPtr root = u.getRoot();
  if (!opt.root_link.empty()) {
    root = u.getLink(opt.root_link);
    if (!root) {
      std::vector<std::string> names;
      for (const auto& [name, link] : u.links_) names.push_back(name);
      throw UrdfRootLinkError(where(source_name) + "root link '" + opt.root_link + "' is not a link of this URDF" +
                              did_you_mean(opt.root_link, names));
    }
  }
  if (!root) throw Error(where(source_name) + "no root link (hint: a URDF needs at least one <link>)");

  ModelDescription d;
  d.name = u.getName();
  LinkSpec r;
  r.name = root->name;
  r.parent = -1;
  r.type = JointType::Fixed;
  r.inertia = inertia(*root);  // welded to the world: kept for completeness, no dynamic effect
  d.add_link(r);
  walk(u, *root, 0, source_name, opt, d, mimics, extras ? &extras->dynamics : nullptr);
  std::vector<UrdfRotor> rotors;
  read_rotors(xml, source_name, u, d, rotors);
  if (extras) extras->rotors = std::move(rotors);
  read_visuals(u, source_name, opt, d);
  if (mimics)  // the leader must be a movable joint of the loaded subtree
    for (const UrdfMimic& mm : *mimics) {
      const auto it = std::find_if(d.links.begin(), d.links.end(),
                                   [&](const LinkSpec& l) { return l.joint_name == mm.leader; });
      if (it == d.links.end() || it->type == JointType::Fixed)
        throw Error(where(source_name) + "joint '" + mm.joint + "' mimics '" + mm.leader + "', which is " +
                    (it == d.links.end() ? "not a joint of the loaded model" : "a fixed joint") +
                    " (hint: mimic a revolute, continuous or prismatic joint below the root link)");
    }

  if (opt.points_for_links) {
    for (const LinkSpec& l : d.links) {
      const bool reserved = l.name == "world" || l.name == "base";
      if (reserved && l.parent >= 0) continue;  // see UrdfOptions::points_for_links
      d.add_point(l.name, l.name, Vec3::Zero());
    }
  }

  // Validate now, so that the error names the file (masses, inertias, limits, finiteness).
  try {
    (void)build_model(d);
  } catch (const Error& e) {
    throw Error(where(source_name) + e.what());
  }
  return d;
}

std::string read_urdf_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error(where(path) + "cannot be read: it is a directory (hint: give the path of a .urdf file)");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f)
    throw Error(where(path) + "cannot be read: " + std::strerror(errno) +
                " (hint: check the path; a relative path is taken from the working directory '" +
                std::filesystem::current_path(ec).string() + "')");
  std::string xml;
  char buf[65536];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) xml.append(buf, n);
  const bool failed = std::ferror(f) != 0;
  const int err = errno;
  std::fclose(f);
  if (failed) throw Error(where(path) + "cannot be read: " + std::strerror(err));
  return xml;
}

}  // namespace

ModelDescription parse_urdf(const std::string& xml, const std::string& source_name, const UrdfOptions& opt,
                            std::vector<UrdfMimic>* mimics) {
  return parse(xml, source_name, opt, mimics, nullptr);
}

ModelDescription parse_urdf(const std::string& xml, const std::string& source_name, const UrdfOptions& opt,
                            UrdfExtras& extras) {
  extras = UrdfExtras{};
  return parse(xml, source_name, opt, &extras.mimics, &extras);
}

ModelDescription load_urdf(const std::string& path, const UrdfOptions& opt, std::vector<UrdfMimic>* mimics) {
  return parse_urdf(read_urdf_file(path), path, opt, mimics);
}

ModelDescription load_urdf(const std::string& path, const UrdfOptions& opt, UrdfExtras& extras) {
  return parse_urdf(read_urdf_file(path), path, opt, extras);
}

}  // namespace refdyn::io
