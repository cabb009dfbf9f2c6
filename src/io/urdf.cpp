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
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

namespace refdyn::io {

namespace {

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
          const UrdfOptions& opt, ModelDescription& d, std::vector<UrdfMimic>* mimics) {
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
    const int ci = d.add_link(l);
    walk(u, *child, ci, source, opt, d, mimics);
  }
}

}  // namespace

ModelDescription parse_urdf(const std::string& xml, const std::string& source_name, const UrdfOptions& opt,
                            std::vector<UrdfMimic>* mimics) {
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
  walk(u, *root, 0, source_name, opt, d, mimics);
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

ModelDescription load_urdf(const std::string& path, const UrdfOptions& opt, std::vector<UrdfMimic>* mimics) {
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
  return parse_urdf(xml, path, opt, mimics);
}

}  // namespace refdyn::io
