// SpecReader and EntryArgs: written values → numbers, names, vectors and functions of time.
#include "refdyn/common/error.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/expression/time_law.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/scenario/schema.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>

namespace refdyn {

void SpecReader::fail(const SourceLocation& at, const std::string& key, const std::string& msg) const {
  std::string where = file_;
  if (at.line > 0) where += ":" + std::to_string(at.line);
  throw Error(where + ": " + (key.empty() ? std::string() : key + ": ") + one_line(msg));
}

std::string SpecReader::one_line(const std::string& msg) {
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

std::string SpecReader::joint_list(const Model& m) {
  std::string s;
  for (const auto& j : m.joint_name) s += (s.empty() ? "" : ", ") + j;
  return s;
}

void SpecReader::keys(const SpecValue& n, const std::string& key, const std::vector<std::string>& allowed) const {
  if (!n.is_map()) fail(n, key, "expected a mapping (key: value lines), got " + n.describe());
  for (const auto& e : n.entries)
    if (std::find(allowed.begin(), allowed.end(), e.key) == allowed.end())
      fail(SourceLocation{n.where.file, e.key_line}, key.empty() ? e.key : key + "." + e.key,
           "unknown key '" + e.key + "'" + did_you_mean(e.key, allowed));
}

const SpecValue& SpecReader::need(const SpecValue& parent, const std::string& k, const std::string& key) const {
  const SpecValue& n = parent[k];
  if (n.is_null()) fail(parent, key.empty() ? k : key + "." + k, "missing (this key is required)");
  return n;
}

Quantity SpecReader::quantity(const SpecValue& n, const std::string& key, const std::map<std::string, double>* extra) const {
  if (!n.is_scalar()) fail(n, key, "expected a number or an expression, got " + n.describe());
  const std::string& s = n.text;
  double v = 0;
  const char* b = s.data();
  const char* e = s.data() + s.size();
  const auto r = std::from_chars(b, e, v);
  if (r.ec == std::errc() && r.ptr == e) {
    if (!std::isfinite(v)) fail(n, key, "expected a finite number, got " + s);
    return Quantity{v, s, n.where, true};
  }
  {  // YAML's special floats: .nan, .inf, -.inf (any case)
    std::string low;
    for (char ch : s) low += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (low == ".nan" || low == ".inf" || low == "+.inf" || low == "-.inf" || low == "nan" || low == "inf" ||
        low == "-inf")
      fail(n, key, "expected a finite number, got " + s);
  }
  const std::map<std::string, double>* p = &params;
  std::map<std::string, double> merged;
  if (extra && !extra->empty()) {
    merged = params;
    for (const auto& [k, x] : *extra) merged[k] = x;
    p = &merged;
  }
  try {
    const Expression ex(s, {}, *p, 0);
    v = ex.value(nullptr);
  } catch (const Error& err) {
    fail(n, key, std::string("expected a number or an expression of the parameters: ") + err.what());
  }
  if (!std::isfinite(v)) fail(n, key, "the expression '" + s + "' is not a finite number");
  return Quantity{v, s, n.where, false};
}

Number3 SpecReader::numbers3(const SpecValue& n, const std::string& key) const {
  vec3(n, key);  // the checks and messages of vec3
  Number3 out;
  for (int k = 0; k < 3; ++k) out[k] = quantity(n[k], key + "[" + std::to_string(k) + "]").number();
  return out;
}

double SpecReader::number_or(const SpecValue& parent, const std::string& k, const std::string& key, double dflt) const {
  const SpecValue& n = parent[k];
  return n ? number(n, key + "." + k) : dflt;
}

std::string SpecReader::string(const SpecValue& n, const std::string& key) const {
  if (!n.is_scalar()) fail(n, key, "expected a text value, got " + n.describe());
  return n.text;
}

bool SpecReader::boolean(const SpecValue& n, const std::string& key) const {
  const std::string s = string(n, key);
  if (s == "true" || s == "yes" || s == "on") return true;
  if (s == "false" || s == "no" || s == "off") return false;
  fail(n, key, "expected true or false, got '" + s + "'");
}

std::string SpecReader::choice(const SpecValue& n, const std::string& key, const std::vector<std::string>& options) const {
  const std::string s = string(n, key);
  if (std::find(options.begin(), options.end(), s) == options.end()) {
    std::string all;
    for (const auto& o : options) all += (all.empty() ? "" : ", ") + o;
    fail(n, key, "expected one of " + all + ", got '" + s + "'" + did_you_mean(s, options));
  }
  return s;
}

Vec3 SpecReader::vec3(const SpecValue& n, const std::string& key) const {
  if (!n.is_list() || n.size() != 3)
    fail(n, key, "expected a list of 3 numbers, got " + n.describe() + (n.is_list() ? " of " + std::to_string(n.size()) : ""));
  return Vec3(number(n[0], key + "[0]"), number(n[1], key + "[1]"), number(n[2], key + "[2]"));
}

SE3 SpecReader::pose(const SpecValue& n, const std::string& key) const {
  keys(n, key, schema::keys("pose"));
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

Eigen::VectorXd SpecReader::joint_vector(const SpecValue& n, const std::string& key, const Model& m, bool all_required,
                                         double dflt, const std::map<std::string, double>* extra) const {
  Eigen::VectorXd v = Eigen::VectorXd::Constant(m.nq, dflt);
  if (n.is_list()) {
    if (static_cast<int>(n.size()) != m.nq)
      fail(n, key, "expected " + std::to_string(m.nq) + " values (one per joint: " + joint_list(m) + "), got " +
                       std::to_string(n.size()));
    for (int i = 0; i < m.nq; ++i) v[i] = number(n[i], key + "[" + std::to_string(i) + "]", extra);
    return v;
  }
  if (!n.is_map()) fail(n, key, "expected a list of numbers or a mapping joint: value, got " + n.describe());
  std::vector<bool> seen(m.nq, false);
  for (const auto& e : n.entries) {
    const auto it = std::find(m.joint_name.begin(), m.joint_name.end(), e.key);
    if (it == m.joint_name.end())
      fail(SourceLocation{n.where.file, e.key_line}, key + "." + e.key,
           "unknown joint '" + e.key + "'" + did_you_mean(e.key, m.joint_name));
    const int idx = static_cast<int>(it - m.joint_name.begin());
    v[idx] = number(e.value, key + "." + e.key, extra);
    seen[idx] = true;
  }
  if (all_required)
    for (int i = 0; i < m.nq; ++i)
      if (!seen[i]) fail(n, key, "missing a value for joint '" + m.joint_name[i] + "' (give all of: " + joint_list(m) + ")");
  return v;
}

std::string SpecReader::joint(const SpecValue& n, const std::string& key, const Model& m) const {
  const std::string j = string(n, key);
  try {
    find_name(m.joint_name, j, "joint");
  } catch (const Error& e) {
    fail(n, key, e.what());
  }
  return j;
}

std::string SpecReader::point(const SpecValue& n, const std::string& key, const Model& m) const {
  const std::string p = string(n, key);
  try {
    find_name(m.point_name, p, "point", " (define it under model.points)");
  } catch (const Error& e) {
    fail(n, key, e.what());
  }
  return p;
}

int SpecReader::axis(const SpecValue& n, const std::string& key) const { return choice(n, key, {"x", "y", "z"})[0] - 'x'; }

TimeFunctionPtr SpecReader::function(const SpecValue& n, const std::string& key) const {
  TimeFunctionPtr f = function_of_task_time(n, key);
  // a time law retimes every function that depends on t (a number or a text without t is constant)
  if (!time_law || (n.is_scalar() && !uses_identifier(n.text, "t"))) return f;
  ++retimed;
  return time_law_function(std::move(f), time_law);
}

TimeFunctionPtr SpecReader::function_of_task_time(const SpecValue& n, const std::string& key) const {
  if (n.is_scalar()) {
    double v = 0;
    const std::string& s = n.text;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v)) return constant(v);
    try {
      return expression_time_function(s, params);
    } catch (const Error& e) {
      fail(n, key, e.what());
    }
  }
  if (n.is_map()) {
    keys(n, key, schema::keys("function of t"));
    if (n.size() != 1) fail(n, key, "expected one of cycloidal or raised_cosine, got " + std::to_string(n.size()));
    if (const SpecValue& cy = n["cycloidal"]) {
      const std::string k = key + ".cycloidal";
      keys(cy, k, schema::keys("function of t.cycloidal"));
      const Number rise = quantity(need(cy, "rise", k), k + ".rise").number();
      const Number dur = quantity(need(cy, "duration", k), k + ".duration").number();
      if (!(dur > 0)) fail(cy["duration"], k + ".duration", "expected a duration > 0 [s], got " + fmt(dur));
      const auto optional = [&](const char* f) { return cy[f] ? quantity(cy[f], k + "." + f).number() : Number(0.0); };
      return cycloidal(rise, dur, optional("from"), optional("start"));
    }
    const SpecValue& rc = n["raised_cosine"];
    const std::string k = key + ".raised_cosine";
    keys(rc, k, schema::keys("function of t.raised_cosine"));
    const Number period = quantity(need(rc, "period", k), k + ".period").number();
    if (!(period > 0)) fail(rc["period"], k + ".period", "expected a period > 0 [s], got " + fmt(period));
    const Number amplitude = quantity(need(rc, "amplitude", k), k + ".amplitude").number();
    return raised_cosine(quantity(need(rc, "base", k), k + ".base").number(), amplitude, period);
  }
  fail(n, key,
       "expected a number, an expression in t, {cycloidal: {rise, duration}} or {raised_cosine: {base, amplitude, "
       "period}}, got " + n.describe());
}

// ---- EntryArgs ----

Number EntryArgs::number(const std::string& k) const {
  return reader.quantity(reader.need(entry.fields, k, entry.key), key(k)).number();
}
Number EntryArgs::number_or(const std::string& k, double dflt) const {
  return has(k) ? reader.quantity(value(k), key(k)).number() : Number(dflt);
}
Number3 EntryArgs::numbers3(const std::string& k) const {
  return reader.numbers3(reader.need(entry.fields, k, entry.key), key(k));
}
std::string EntryArgs::text(const std::string& k) const { return reader.string(reader.need(entry.fields, k, entry.key), key(k)); }
std::string EntryArgs::joint(const std::string& k) const {
  return reader.joint(reader.need(entry.fields, k, entry.key), key(k), model);
}
std::string EntryArgs::point(const std::string& k) const {
  return reader.point(reader.need(entry.fields, k, entry.key), key(k), model);
}
Vec3 EntryArgs::vec3(const std::string& k) const { return reader.vec3(reader.need(entry.fields, k, entry.key), key(k)); }
TimeFunctionPtr EntryArgs::function(const std::string& k) const {
  return reader.function(reader.need(entry.fields, k, entry.key), key(k));
}
Eigen::VectorXd EntryArgs::joint_vector(const std::string& k, bool all_required, double dflt) const {
  return reader.joint_vector(reader.need(entry.fields, k, entry.key), key(k), model, all_required, dflt);
}
void EntryArgs::fail(const std::string& k, const std::string& msg) const {
  const SpecValue& v = value(k);
  reader.fail(v ? v.where : entry.fields.where, k.empty() ? entry.key : key(k), msg);
}

}  // namespace refdyn
