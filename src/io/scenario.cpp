// Scenario YAML → ScenarioSpec. Structure only: numbers stay text (build_problem evaluates them).
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/variants.hpp"

#include "scenario_sections.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/io/urdf.hpp"
#include "refdyn/scenario/registry.hpp"
#include "refdyn/scenario/schema.hpp"
#include "refdyn/common/text.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <set>
#include <sstream>
#include <sys/stat.h>

namespace refdyn::io {

namespace {

namespace fs = std::filesystem;

/// Most values a scenario may hold after YAML aliases are expanded: aliases share nodes in
/// yaml-cpp, so a few lines (`b: [*a, *a, …]` nested) can stand for billions of values.
constexpr long kMaxSpecValues = 1'000'000;

/// Deepest nesting of lists and mappings a scenario may have (a real one has about six levels). An
/// alias inside its own anchor (`a: &a [*a]`) makes a cycle in yaml-cpp's node graph, which
/// would otherwise be followed until the stack overflows (found by the fuzzers).
constexpr int kMaxSpecDepth = 64;

/// Whether the quoted scalar that starts at text[pos] (a ' or a ") has its closing quote.
/// yaml-cpp 0.7 accepts a quote left open: the value then runs on to the end of the file, which
/// swallows every later key (found by a user: `name: "arm` gave "model: missing").
bool quote_closed(const std::string& text, size_t pos) {
  const char q = text[pos];
  for (size_t i = pos + 1; i < text.size(); ++i) {
    if (q == '"' && text[i] == '\\') {
      ++i;  // an escape: \" or \\ is not the end
    } else if (text[i] == q) {
      if (q == '\'' && i + 1 < text.size() && text[i + 1] == '\'') {
        ++i;  // '' inside single quotes is one quote
      } else {
        return true;
      }
    }
  }
  return false;
}

/// The line (1-based) where a quoted value starts that never ends, or 0: a hint for a YAML syntax
/// error that yaml-cpp reports elsewhere (`q: {j1: "0, j2: 1}` gives "end of map flow not found").
/// A quote opens a value only at its start (after a line's indentation, ': ', '- ', '[', '{' or
/// ','); comments are skipped.
int unterminated_quote_line(const std::string& text) {
  int line = 1;
  char prev = '\n';  // the last character that is not a space or a tab
  for (size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (ch == '\n') {
      ++line;
      prev = '\n';
      continue;
    }
    if (ch == ' ' || ch == '\t') continue;
    if (ch == '#' && (i == 0 || text[i - 1] == ' ' || text[i - 1] == '\t' || text[i - 1] == '\n')) {
      while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
      continue;
    }
    const bool at_value_start = prev == '\n' || prev == '[' || prev == '{' || prev == ',' ||
                                ((prev == ':' || prev == '-' || prev == '?') && i > 0 && (text[i - 1] == ' ' || text[i - 1] == '\t'));
    if ((ch == '"' || ch == '\'') && at_value_start) {
      if (!quote_closed(text, i)) return line;
      const char q = ch;
      for (++i; i < text.size(); ++i) {  // to the closing quote, counting lines
        if (text[i] == '\n') ++line;
        if (q == '"' && text[i] == '\\') {
          if (i + 1 < text.size() && text[i + 1] == '\n') ++line;
          ++i;
        } else if (text[i] == q) {
          if (q == '\'' && i + 1 < text.size() && text[i + 1] == '\'') ++i;
          else break;
        }
      }
    }
    prev = ch;
  }
  return 0;
}

/// YAML → SpecValue: scalar keys only, each key once (both lines named otherwise). `text` is the
/// file's text (to find quoted values that never end).
SpecValue to_spec(const YAML::Node& n, const std::string& file, const std::string& key, const SpecReader& r,
                  long& budget, const std::string& text, int depth = 0) {
  if (depth > kMaxSpecDepth)
    r.fail(SourceLocation{file, n.Mark().is_null() ? 0 : n.Mark().line + 1},
           key.size() > 48 ? key.substr(0, 48) + "..." : key,
           "lists and mappings nested deeper than " + std::to_string(kMaxSpecDepth) +
               " levels (a YAML alias used inside its own anchor?); a scenario is far shallower");
  if (--budget < 0)
    r.fail(SourceLocation{file, n.Mark().is_null() ? 0 : n.Mark().line + 1}, key,
           "the file expands to more than " + std::to_string(kMaxSpecValues) +
               " values (YAML aliases repeated inside aliases?); a scenario is far smaller");
  SpecValue v;
  v.where = {file, n.Mark().is_null() ? 0 : n.Mark().line + 1, n.Mark().is_null() ? 0 : n.Mark().column + 1};
  switch (n.Type()) {
    case YAML::NodeType::Undefined:
    case YAML::NodeType::Null:
      v.kind = SpecValue::Kind::Null;
      break;
    case YAML::NodeType::Scalar:
      v.kind = SpecValue::Kind::Scalar;
      v.text = n.Scalar();
      if (!n.Mark().is_null() && n.Mark().pos >= 0 && static_cast<size_t>(n.Mark().pos) < text.size() &&
          (text[n.Mark().pos] == '"' || text[n.Mark().pos] == '\'') && !quote_closed(text, n.Mark().pos)) {
        const char q = text[n.Mark().pos];
        std::string start = text.substr(n.Mark().pos, 24);
        if (const auto nl = start.find('\n'); nl != std::string::npos) start = start.substr(0, nl);
        r.fail(v.where, key,
               std::string("the quoted text that starts here (") + start + ") never ends: no closing " + q +
                   " before the end of the file (hint: add the closing " + q + ")");
      }
      break;
    case YAML::NodeType::Sequence:
      v.kind = SpecValue::Kind::List;
      for (size_t i = 0; i < n.size(); ++i)
        v.items.push_back(to_spec(n[i], file, key + "[" + std::to_string(i) + "]", r, budget, text, depth + 1));
      break;
    case YAML::NodeType::Map:
      v.kind = SpecValue::Kind::Map;
      for (const auto& kv : n) {
        const int line = kv.first.Mark().is_null() ? v.where.line : kv.first.Mark().line + 1;
        if (!kv.first.IsScalar())
          r.fail(SourceLocation{file, line}, key,
                 "expected a plain name as a mapping key, got " + std::string(kv.first.IsSequence() ? "a list" : "a mapping") +
                     " (hint: remove the '? ' or brackets before the key)");
        const std::string k = kv.first.Scalar();
        const std::string child = key.empty() ? k : key + "." + k;
        for (const auto& e : v.entries)
          if (e.key == k)
            r.fail(SourceLocation{file, line}, child,
                   "key '" + k + "' is given twice (lines " + std::to_string(e.key_line) + " and " + std::to_string(line) +
                       "); keep one");
        v.entries.push_back({k, line, to_spec(kv.second, file, child, r, budget, text, depth + 1)});
      }
      break;
  }
  return v;
}

/// Counts documents (and where the last one started) without building nodes.
struct DocumentCounter final : YAML::EventHandler {
  int last_start_line = 0;
  void OnDocumentStart(const YAML::Mark& m) override { last_start_line = m.is_null() ? 0 : m.line + 1; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

/// Every key some kind of the registry allows: an entry's keys are checked against these before
/// its required keys are looked up, so that a misspelt key (`expresion:`) is reported as such and
/// not as the required key it hides (`kind: missing`).
template <class Kind>
std::vector<std::string> any_kind_keys(const Registry<Kind>& reg) {
  std::vector<std::string> all;
  for (const Kind& k : reg.entries())
    for (const std::string& key : allowed_keys(k))
      if (std::find(all.begin(), all.end(), key) == all.end()) all.push_back(key);
  return all;
}

/// Reads the structure of the file; `c` only locates errors (it evaluates nothing here).
class Reader {
 public:
  explicit Reader(const SpecReader& c) : c_(c) {}

  std::vector<EntrySpec> constraints(const SpecValue& n) const {
    std::vector<EntrySpec> out;
    if (!n) return out;
    if (!n.is_list()) c_.fail(n, "constraints", "expected a list of constraints, got " + n.describe());
    std::set<std::string> names;
    for (size_t i = 0; i < n.size(); ++i) {
      const SpecValue& e = n[i];
      const std::string k = "constraints[" + std::to_string(i) + "]";
      if (!e.is_map()) c_.fail(e, k, "expected a mapping with 'name' and 'expression' or 'kind', got " + e.describe());
      c_.keys(e, k, any_kind_keys(constraint_kinds()));  // unknown keys before missing ones
      EntrySpec s;
      s.name = c_.string(c_.need(e, "name", k), k + ".name");
      if (!names.insert(s.name).second)
        c_.fail(e["name"], "constraints." + s.name, "constraint '" + s.name + "' is defined twice (names must be unique)");
      s.key = "constraints." + s.name;
      s.fields = e;
      if (e["expression"] && !e["kind"]) {
        s.kind = "expression";
      } else {
        s.kind = c_.string(c_.need(e, "kind", s.key), s.key + ".kind");
      }
      const ConstraintKind* kind = constraint_kinds().find(s.kind);
      if (!kind)
        c_.fail(e["kind"], s.key + ".kind",
                "unknown constraint kind '" + s.kind + "'" + did_you_mean(s.kind, constraint_kinds().names()));
      c_.keys(e, k, allowed_keys(*kind));
      out.push_back(std::move(s));
    }
    return out;
  }

  std::optional<std::vector<EntrySpec>> forces(const SpecValue& n, const std::string& key) const {
    std::vector<EntrySpec> out;
    if (!n || (n.is_scalar() && n.text == "none")) return out;
    if (!n.is_list()) c_.fail(n, key, "expected a list of force elements (or 'none'), got " + n.describe());
    for (size_t i = 0; i < n.size(); ++i) {
      const SpecValue& f = n[i];
      EntrySpec s;
      s.key = key + "[" + std::to_string(i) + "]";
      if (!f.is_map()) c_.fail(f, s.key, "expected a mapping with a 'type', got " + f.describe());
      c_.keys(f, s.key, any_kind_keys(force_kinds()));  // unknown keys before missing ones
      s.kind = c_.choice(c_.need(f, "type", s.key), s.key + ".type", force_kinds().names());
      if (f["name"]) s.name = c_.string(f["name"], s.key + ".name");
      s.fields = f;
      c_.keys(f, s.key, allowed_keys(*force_kinds().find(s.kind)));
      out.push_back(std::move(s));
    }
    return out;
  }

  EntrySpec controller(const SpecValue& n, const std::string& key) const {
    EntrySpec s;
    s.key = key;
    if (!n.is_map()) c_.fail(n, key, "expected a mapping with a 'type', got " + n.describe());
    c_.keys(n, key, any_kind_keys(controller_kinds()));  // unknown keys before missing ones
    s.kind = c_.choice(c_.need(n, "type", key), key + ".type", controller_kinds().names());
    s.fields = n;
    c_.keys(n, key, allowed_keys(*controller_kinds().find(s.kind)));
    return s;
  }

 private:
  const SpecReader& c_;
};

/// monte_carlo: {samples, seed, distributions: {name: {normal: {mean, std}} | {uniform: {low, high}}}};
/// the numbers stay text (build_problem evaluates and checks them).
MonteCarloSpec monte_carlo(const SpecReader& c, const SpecValue& mc, const std::string& key) {
  c.keys(mc, key, schema::keys("monte_carlo"));
  MonteCarloSpec m;
  m.value = mc;
  m.samples = c.need(mc, "samples", key);
  m.seed = c.need(mc, "seed", key);
  const SpecValue& ds = c.need(mc, "distributions", key);
  if (!ds.is_map() || ds.size() == 0)
    c.fail(ds, key + ".distributions",
           "expected a mapping  name: {normal: {mean: ..., std: ...}} or {uniform: {low: ..., high: ...}}  with at least "
           "one parameter, got " + ds.describe());
  const std::vector<std::string>& kinds = schema::keys("monte_carlo.distributions.<p>");
  for (const auto& en : ds.entries) {
    const std::string dk = key + ".distributions." + en.key;
    const SpecValue& d = en.value;
    if (!d.is_map() || d.size() != 1)
      c.fail(d.where.line ? d.where : SourceLocation{d.where.file, en.key_line}, dk,
             "expected exactly one distribution, {normal: {mean: ..., std: ...}} or {uniform: {low: ..., high: ...}}, got " +
                 (d.is_map() ? std::to_string(d.size()) + " entries" : d.describe()));
    const SpecValue::Entry& kind = d.entries[0];
    if (std::find(kinds.begin(), kinds.end(), kind.key) == kinds.end())
      c.fail(SourceLocation{d.where.file, kind.key_line}, dk + "." + kind.key,
             "unknown distribution '" + kind.key + "'" + did_you_mean(kind.key, kinds));
    const std::vector<std::string>& ab = schema::keys("monte_carlo.distributions.<p>." + kind.key);  // {a, b}
    const std::string& first = ab.at(0);
    const std::string& second = ab.at(1);
    c.keys(kind.value, dk + "." + kind.key, ab);
    DistributionSpec s;
    s.parameter = en.key;
    s.kind = kind.key;
    s.a = c.need(kind.value, first, dk + "." + kind.key);
    s.b = c.need(kind.value, second, dk + "." + kind.key);
    s.value = d;
    m.distributions.push_back(std::move(s));
  }
  return m;
}

}  // namespace

std::string read_text_file(const std::string& path, const std::string& what, std::size_t max_bytes) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw Error(what + " '" + path + "': cannot be read: " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw Error(what + " '" + path + "': cannot be read: it is a folder, not a file");
  if (!S_ISREG(st.st_mode))
    throw Error(what + " '" + path + "': cannot be read: not a regular file (devices, pipes and sockets are refused)");
  if (static_cast<std::size_t>(st.st_size) > max_bytes)
    throw Error(what + " '" + path + "': " + std::to_string(st.st_size) + " bytes, more than the limit of " +
                std::to_string(max_bytes) + " bytes (hint: --max-input-size BYTES raises it)");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error(what + " '" + path + "': cannot be read: " + std::strerror(errno));
  std::string text;
  char buf[65536];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) {
    text.append(buf, n);
    if (text.size() > max_bytes) {
      std::fclose(f);
      throw Error(what + " '" + path + "': more than the limit of " + std::to_string(max_bytes) +
                  " bytes (hint: --max-input-size BYTES raises it)");
    }
  }
  const bool bad = std::ferror(f);
  std::fclose(f);
  if (bad) throw Error(what + " '" + path + "': read error");
  return text;
}

namespace {

/// The text as one YAML document (syntax errors located, with a hint for tabs and open quotes).
YAML::Node load_yaml(const SpecReader& c, const std::string& text, const std::string& source) {
  // Count the documents first (at most two: yaml-cpp's LoadAll loops for ever on some malformed
  // input, e.g. "\t,pap", producing empty documents), then load the first one.
  YAML::Node yroot;
  int documents = 0, second_line = 0;
  try {
    std::istringstream in(text);
    YAML::Parser parser(in);
    DocumentCounter counter;
    while (documents < 2 && parser.HandleNextDocument(counter)) {
      if (++documents == 2) second_line = counter.last_start_line;
    }
    if (documents <= 1) yroot = YAML::Load(text);
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
    if (hint.empty())
      if (const int q = unterminated_quote_line(text))
        hint = " (hint: the quoted text that starts on line " + std::to_string(q) + " never ends; add its closing quote)";
    throw Error(source + (e.mark.is_null() ? "" : ":" + std::to_string(e.mark.line + 1)) +
                ": YAML syntax error: " + SpecReader::one_line(e.msg) + hint);
  }
  if (documents > 1)
    c.fail(SourceLocation{source, second_line}, "",
           "a second YAML document (after '---'): a scenario file holds exactly one; remove it or split the file");
  if (!yroot.IsMap()) throw Error(source + ": expected a YAML mapping at the top level (keys such as model:, constraints:)");
  return yroot;
}

/// The shortest text that reads back as v.
std::string number_text(double v) {
  char b[32];
  const auto r = std::to_chars(b, b + sizeof b, v);
  return std::string(b, r.ptr);
}

/// LuGre bristle stiffness of a URDF joint's Coulomb friction F, per newton metre of F: σ0 = 100 F
/// [N m/rad] (breakaway deflection F/σ0 = 0.01 rad; docs/scenario.md "model").
constexpr double kUrdfFrictionStiffness = 100.0;
constexpr double kUrdfStribeckVelocity = 0.01;  ///< [rad/s]; no effect with μs = μk

/// The URDF's <dynamics damping friction>: with model.urdf.dynamics: true, force elements written
/// ahead of the file's own forces (damping b; LuGre with μs = μk = F), as if the file had them;
/// else a note that they are ignored.
void urdf_dynamics(const SpecReader& c, const SpecValue& u, const std::vector<UrdfJointDynamics>& dyn, ScenarioSpec& s) {
  const bool use = u["dynamics"] && c.boolean(u["dynamics"], "model.urdf.dynamics");
  if (dyn.empty()) return;
  std::string joints;
  for (const UrdfJointDynamics& d : dyn) joints += (joints.empty() ? "" : ", ") + d.joint;
  if (!use) {
    s.model.notes.push_back("the URDF's <dynamics> (damping, friction) of joints " + joints +
                            " are ignored (model.urdf.dynamics: true adds them as damping and LuGre friction forces)");
    return;
  }
  const SourceLocation at = u.key_location("dynamics");
  auto scalar = [&](const std::string& t) { return SpecValue::scalar(t, at); };
  auto entry = [&](const std::string& type, const std::string& joint,
                   std::vector<std::pair<std::string, std::string>> fields) {
    EntrySpec e;
    e.kind = type;
    e.key = "model.urdf.dynamics (" + type + " of joint " + joint + ")";
    e.fields.kind = SpecValue::Kind::Map;
    e.fields.where = at;
    fields.insert(fields.begin(), {{"type", type}, {"joint", joint}});
    for (auto& [k, v] : fields) e.fields.entries.push_back({k, at.line, scalar(v)});
    return e;
  };
  std::vector<EntrySpec> added;
  std::string damped, rubbing;
  for (const UrdfJointDynamics& d : dyn) {
    if (d.damping > 0) {
      added.push_back(entry("damping", d.joint, {{"coefficient", number_text(d.damping)}}));
      damped += (damped.empty() ? "" : ", ") + d.joint;
    }
    if (d.friction > 0) rubbing += (rubbing.empty() ? "" : ", ") + d.joint;
    if (d.friction > 0)
      added.push_back(entry("lugre", d.joint,
                            {{"mu_s", number_text(d.friction)},
                             {"mu_k", number_text(d.friction)},
                             {"sigma0", number_text(kUrdfFrictionStiffness * d.friction)},
                             {"sigma1", "0"},
                             {"sigma2", "0"},
                             {"stribeck_velocity", number_text(kUrdfStribeckVelocity)}}));
  }
  s.forces.insert(s.forces.begin(), added.begin(), added.end());
  s.model.notes.push_back("the URDF's <dynamics> are force elements (model.urdf.dynamics): " +
                          (damped.empty() ? std::string() : "damping on " + damped) +
                          (damped.empty() || rubbing.empty() ? "" : "; ") +
                          (rubbing.empty() ? std::string()
                                           : "LuGre friction (mu_s = mu_k = F, sigma0 = " +
                                                 number_text(kUrdfFrictionStiffness) + " F per rad) on " + rubbing));
}

/// parameters: and model: (a URDF model is read here, with its <mimic> couplings).
void read_parameters_and_model(const SpecReader& c, const SpecValue& root, std::size_t max_input_bytes, ScenarioSpec& s) {
  const std::string& source = s.file;
  if (const SpecValue& p = root["parameters"]) {
    if (!p.is_map()) c.fail(p, "parameters", "expected a mapping name: value");
    for (const auto& e : p.entries) s.parameters.emplace_back(e.key, e.value);
  }

  s.model.value = c.need(root, "model", "");
  if (const SpecValue& u = s.model.value["urdf"]) {
    c.keys(u, "model.urdf", schema::keys("model.urdf"));
    const std::string f = c.string(c.need(u, "file", "model.urdf"), "model.urdf.file");
    const fs::path here = fs::path(source).parent_path();
    fs::path p(f);
    if (p.is_relative()) p = here / p;
    UrdfOptions uo;
    if (u["root"]) uo.root_link = c.string(u["root"], "model.urdf.root");
    uo.root_link_option = "model.urdf.root";  // the hints name the scenario key
    if (const SpecValue& pk = u["packages"]) {  // {name: folder}, folders relative to the scenario file
      if (!pk.is_map()) c.fail(pk, "model.urdf.packages", "expected a mapping package: folder, got " + pk.describe());
      for (const auto& e : pk.entries) {
        const fs::path folder(c.string(e.value, "model.urdf.packages." + e.key));
        uo.packages[e.key] = (folder.is_relative() ? here / folder : folder).string();
      }
    }
    UrdfExtras extras;
    try {
      s.model.urdf = parse_urdf(read_text_file(p.string(), "URDF file", max_input_bytes), p.string(), uo, extras);
    } catch (const UrdfRootLinkError& e) {  // the file is fine; the key names a link it lacks
      c.fail(u["root"], "model.urdf.root", e.what());
    } catch (const Error& e) {
      c.fail(u["file"], "model.urdf.file", e.what());
    }
    for (const auto& m : extras.mimics) s.model.mimics.push_back({m.joint, m.leader, m.multiplier, m.offset});
    if (!extras.rotors.empty()) {  // one line: joint armature (rotor inertia x gear ratio^2), ...
      std::string list;
      for (const UrdfRotor& r : extras.rotors)
        list += (list.empty() ? "" : ", ") + r.joint + " " + fmt(r.armature()) + " (" + fmt(r.rotor_inertia) + " x " +
                fmt(r.gear_ratio) + "^2)";
      s.model.notes.push_back("armature [kg m^2] from the URDF's <drake:rotor_inertia> x <drake:gear_ratio>^2: " + list);
    }
    urdf_dynamics(c, u, extras.dynamics, s);
  }
}

/// baumgarte:, solver:, paper_literal_forces:, partition:, initial: and integrator:.
void read_solver_sections(const SpecReader& c, const SpecValue& root, ScenarioSpec& s) {
  if (const SpecValue& b = root["baumgarte"]) {
    c.keys(b, "baumgarte", schema::keys("baumgarte"));
    s.baumgarte = {b["alpha"], b["beta"], b["beta_first_order"], b, b["kappa"]};
  }
  if (const SpecValue& st = root["stabilization"]) {  // baumgarte | projection | both, or {method, tolerance, max_iterations}
    const SpecValue* method = &st;
    if (!st.is_scalar()) {
      c.keys(st, "stabilization", schema::keys("stabilization"));
      method = &c.need(st, "method", "stabilization");
      s.stabilization.tolerance = st["tolerance"];
      s.stabilization.max_iterations = st["max_iterations"];
    }
    s.stabilization.method = c.choice(*method, "stabilization", schema::choices("stabilization", "method"));
    s.stabilization.value = st;
  }
  if (root["solver"]) s.solver = c.choice(root["solver"], "solver", schema::choices("", "solver"));
  if (root["paper_literal_forces"]) s.paper_literal_forces = c.boolean(root["paper_literal_forces"], "paper_literal_forces");

  const SpecValue& part = root["partition"];
  s.partition.value = part;
  if (part && !(part.is_scalar() && part.text == "auto")) {
    c.keys(part, "partition", schema::keys("partition"));
    const SpecValue& ind = c.need(part, "independent", "partition");
    s.partition.automatic_switch = part["automatic_switch"];
    s.partition.max_condition = part["max_condition"];
    if (!(ind.is_scalar() && ind.text == "auto")) {
      if (!ind.is_list())
        c.fail(ind, "partition.independent", "expected a list of joint names or 'auto', got " + ind.describe());
      s.partition.automatic = false;
      s.partition.independent_value = ind;
      for (size_t i = 0; i < ind.size(); ++i) s.partition.independent.push_back(c.string(ind[i], "partition.independent"));
    }
  }

  const SpecValue& ini = c.need(root, "initial", "");
  c.keys(ini, "initial", schema::keys("initial"));
  c.need(ini, "q", "initial");
  s.initial = {ini["q"], ini["qd"], false, ini["tolerance"], ini, ini["qdd"]};
  if (ini["consistency"]) s.initial.project = c.choice(ini["consistency"], "initial.consistency", schema::choices("initial", "consistency")) == "project";

  if (const SpecValue& in = root["integrator"]) {
    c.keys(in, "integrator", schema::keys("integrator"));
    IntegratorSpec& o = s.integrator;
    if (in["method"]) o.method = c.choice(in["method"], "integrator.method", schema::choices("integrator", "method"));
    o.max_order = in["max_order"];
    o.step = in["step"];
    o.t0 = in["t0"];
    o.t1 = in["t1"];
    o.rtol = in["rtol"];
    o.atol = in["atol"];
    o.output_interval = in["output_interval"];
    o.min_step = in["min_step"];
    o.residual_from = in["residual_from"];
    o.residual_tolerance = in["residual_tolerance"];
    o.value = in;
  }
}

/// One entry of experiments:.
ExperimentSpec read_experiment(const SpecReader& c, const Reader& rd, const SpecValue& ex, size_t i,
                               const std::string& source) {
  const SpecValue& e = ex[i];
  ExperimentSpec x;
  x.key = "experiments[" + std::to_string(i) + "]";
  c.keys(e, x.key, schema::keys("experiments[]"));
  x.value = e;
  {  // at most one way of expanding an experiment into runs; the second one written is named
    std::vector<const SpecValue::Entry*> given;
    for (const auto& en : e.entries)
      if (en.key == "sweep" || en.key == "grid" || en.key == "monte_carlo") given.push_back(&en);
    if (given.size() > 1)
      c.fail(SourceLocation{source, given[1]->key_line}, x.key + "." + given[1]->key,
             "an experiment has at most one of sweep, grid and monte_carlo, got '" + given[0]->key + "' and '" +
                 given[1]->key + "' (hint: put every parameter into one grid, or split it into two experiments)");
  }
  if (e["name"]) {
    x.name = c.string(e["name"], x.key + ".name");
    x.named = true;
  }
  if (const SpecValue& sw = e["sweep"]) {
    if (!sw.is_map() || sw.size() != 1) c.fail(sw, x.key + ".sweep", "expected one entry  name: [values]");
    x.sweep = sw;
    x.sweep_parameter = sw.entries[0].key;
    const SpecValue& vs = sw.entries[0].value;
    if (!vs.is_list() || vs.size() == 0)
      c.fail(vs, x.key + ".sweep." + x.sweep_parameter, "expected a non-empty list of values");
    x.sweep_values = vs.items;
  }
  const auto given = [&](const std::string& k) {  // written, even with an empty value
    return std::any_of(e.entries.begin(), e.entries.end(), [&](const auto& en) { return en.key == k; });
  };
  if (given("grid")) {
    const SpecValue& g = e["grid"];
    if (!g.is_map() || g.size() == 0)
      c.fail(e.key_location("grid"), x.key + ".grid",
             "expected a mapping  name: [values]  with at least one parameter, got " + g.describe());
    for (const auto& en : g.entries) {
      if (!en.value.is_list() || en.value.size() == 0)
        c.fail(en.value.where.line ? en.value.where : SourceLocation{source, en.key_line}, x.key + ".grid." + en.key,
               "expected a non-empty list of values, got " + en.value.describe());
      x.grid.emplace_back(en.key, en.value.items);
    }
    x.grid_value = g;
  }
  if (given("monte_carlo")) {
    if (!e["monte_carlo"].is_map())
      c.fail(e.key_location("monte_carlo"), x.key + ".monte_carlo",
             "expected a mapping with samples, seed and distributions, got " + e["monte_carlo"].describe());
    x.monte_carlo = monte_carlo(c, e["monte_carlo"], x.key + ".monte_carlo");
  }
  if (const SpecValue& in = e["initial"]) {
    c.keys(in, x.key + ".initial", schema::keys("experiments[].initial"));
    x.initial_q = in["q"];
    x.initial_qd = in["qd"];
  }
  if (e["plant_forces"]) x.plant_forces = rd.forces(e["plant_forces"], x.key + ".plant_forces");
  if (const SpecValue& ct = e["controller"]) x.controller = rd.controller(ct, x.key + ".controller");
  return x;
}

}  // namespace

ScenarioSpec parse_scenario(const std::string& text, const std::string& source, std::size_t max_input_bytes) {
  const SpecReader c(source, {});
  if (text.size() > max_input_bytes)
    throw Error(source + ": " + std::to_string(text.size()) + " bytes, more than the limit of " +
                std::to_string(max_input_bytes) + " bytes");
  const YAML::Node yroot = load_yaml(c, text, source);
  ScenarioSpec s;
  s.file = source;
  long budget = kMaxSpecValues;
  s.root = to_spec(yroot, source, "", c, budget, text);
  const SpecValue& root = s.root;
  c.keys(root, "", schema::keys(""));
  const Reader rd(c);
  s.name = root["name"] ? c.string(root["name"], "name") : fs::path(source).stem().string();

  read_parameters_and_model(c, root, max_input_bytes, s);

  s.constraints_value = root["constraints"];
  s.constraints = rd.constraints(root["constraints"]);
  {
    std::vector<EntrySpec> urdf_forces = std::move(s.forces);  // model.urdf.dynamics: ahead of the file's
    s.forces = *rd.forces(root["forces"], "forces");
    s.forces.insert(s.forces.begin(), urdf_forces.begin(), urdf_forces.end());
  }
  if (root["plant_forces"]) s.plant_forces = rd.forces(root["plant_forces"], "plant_forces");

  read_solver_sections(c, root, s);

  if (const SpecValue& ct = root["controller"]) s.controller = rd.controller(ct, "controller");
  s.effort_limit = root["effort_limit"];
  s.actuators = root["actuators"];
  s.experiments_value = root["experiments"];
  if (const SpecValue& ex = root["experiments"]) {
    if (!ex.is_list()) c.fail(ex, "experiments", "expected a list of experiments");
    for (size_t i = 0; i < ex.size(); ++i) s.experiments.push_back(read_experiment(c, rd, ex, i, source));
  }
  if (const SpecValue& va = root["variants"]) s.variants = detail::read_variants(c, va);
  if (root["optimize"] || std::any_of(root.entries.begin(), root.entries.end(), [](const auto& e) { return e.key == "optimize"; }))
    s.optimize = detail::read_optimize(c, root["optimize"], root.key_location("optimize"));
  if (const SpecValue& tl = root["time_law"]) {
    c.keys(tl, "time_law", schema::keys("time_law"));
    s.time_law = tl;
  }
  if (const SpecValue& lim = root["limits"]) {
    c.keys(lim, "limits", schema::keys("limits"));
    s.limits = lim;
  }
  if (const SpecValue& out = root["outputs"]) {
    c.keys(out, "outputs", schema::keys("outputs"));
    std::vector<SpecValue> pts;
    if (const SpecValue& ps = out["points"]) {
      if (!ps.is_list()) c.fail(ps, "outputs.points", "expected a list of point names");
      pts = ps.items;
    }
    s.output_points = pts;
  }
  return s;
}

SpecValue parse_yaml_tree(const std::string& text, const std::string& source) {
  const SpecReader c(source, {});
  long budget = kMaxSpecValues;
  return to_spec(load_yaml(c, text, source), source, "", c, budget, text);
}

ScenarioSpec load_scenario(const std::string& path, std::size_t max_input_bytes) {
  return parse_scenario(read_text_file(path, "scenario file", max_input_bytes), path, max_input_bytes);
}

namespace {
/// build_problem, and the `variants:` section checked too (the whole file is valid or an error).
std::unique_ptr<Problem> build_checked(const ScenarioSpec& spec) {
  auto p = build_problem(spec);
  (void)expand_variants(spec);
  return p;
}
}  // namespace

std::unique_ptr<Problem> load_problem(const std::string& path, std::size_t max_input_bytes) {
  return build_checked(load_scenario(path, max_input_bytes));
}

std::unique_ptr<Problem> parse_problem(const std::string& yaml, const std::string& source_name) {
  return build_checked(parse_scenario(yaml, source_name));
}

}  // namespace refdyn::io
