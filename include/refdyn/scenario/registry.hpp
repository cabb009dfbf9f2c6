#pragma once
/// Registries of the extensible parts of a scenario: constraint kinds, force elements and
/// controllers. Each entry owns its keys (names, types, defaults, documentation) and its
/// factory; the YAML layer checks keys against the entry, build_problem calls the factory, and
/// `refdyn kinds` prints the documentation. Adding a kind is one new file in src/kinds/ (a
/// function returning the entry) plus one line in src/kinds/kinds.def.
///
/// SpecReader is the one place where written values become numbers, names and functions, with
/// errors "FILE:LINE: KEY: message"; factories read their fields through EntryArgs.

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/simulate/controllers.hpp"
#include "refdyn/forces/force_elements.hpp"
#include "refdyn/scenario/spec.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/expression/time_function.hpp"
#include "refdyn/expression/time_law.hpp"

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace refdyn {

/// Reads and checks written values. Numbers may be expressions of the parameters.
class SpecReader {
 public:
  SpecReader(std::string file, std::map<std::string, double> parameters)
      : params(std::move(parameters)), file_(std::move(file)) {}
  const std::string& file() const { return file_; }
  std::map<std::string, double> params;  ///< visible parameters (deg, the scenario's, a sweep's)
  /// List parameters (`v: [0.5, 0.5, …]`), element by element (value, text, where).
  std::map<std::string, std::vector<Quantity>> lists;
  /// The scenario's `time_law:` (none: real time is task time). function() returns every
  /// time-dependent function f as f(s(t)) and counts it in `retimed`.
  TimeLawPtr time_law;
  mutable int retimed = 0;

  /// Throws Error "FILE:LINE: KEY: message" (message made one line; LINE omitted if unknown).
  [[noreturn]] void fail(const SourceLocation& at, const std::string& key, const std::string& msg) const;
  [[noreturn]] void fail(const SpecValue& at, const std::string& key, const std::string& msg) const {
    fail(at.where, key, msg);
  }
  /// Unknown keys of mapping `n` (not in `allowed`) are errors with "did you mean".
  void keys(const SpecValue& n, const std::string& key, const std::vector<std::string>& allowed) const;
  /// parent[k], required.
  const SpecValue& need(const SpecValue& parent, const std::string& k, const std::string& key) const;
  /// A written number or expression of the parameters (and `extra`), evaluated once: its value,
  /// its text and where it was written. Errors for anything else or a value that is not finite.
  Quantity quantity(const SpecValue& n, const std::string& key, const std::map<std::string, double>* extra = nullptr) const;
  double number(const SpecValue& n, const std::string& key, const std::map<std::string, double>* extra = nullptr) const {
    return quantity(n, key, extra).value;
  }
  /// Three numbers [x, y, z] with their texts.
  Number3 numbers3(const SpecValue& n, const std::string& key) const;
  double number_or(const SpecValue& parent, const std::string& k, const std::string& key, double dflt) const;
  std::string string(const SpecValue& n, const std::string& key) const;
  bool boolean(const SpecValue& n, const std::string& key) const;
  std::string choice(const SpecValue& n, const std::string& key, const std::vector<std::string>& options) const;
  Vec3 vec3(const SpecValue& n, const std::string& key) const;
  SE3 pose(const SpecValue& n, const std::string& key) const;
  /// A per-joint vector: a list in joint order or a mapping joint: value.
  Eigen::VectorXd joint_vector(const SpecValue& n, const std::string& key, const Model& m, bool all_required,
                               double dflt, const std::map<std::string, double>* extra = nullptr) const;
  std::string joint(const SpecValue& n, const std::string& key, const Model& m) const;
  std::string point(const SpecValue& n, const std::string& key, const Model& m) const;
  /// A function of t: a number, an expression in t and the parameters, {cycloidal: {rise,
  /// duration, from, start}} or {raised_cosine: {base, amplitude, period}}.
  /// Under a time law (time_law above) the function of task time f(τ) as f(s(t)).
  TimeFunctionPtr function(const SpecValue& n, const std::string& key) const;
  /// The function as written, in task time (no time law applied).
  TimeFunctionPtr function_of_task_time(const SpecValue& n, const std::string& key) const;
  int axis(const SpecValue& n, const std::string& key) const;  ///< x | y | z → 0 | 1 | 2

  /// Multi-line diagnostics joined into one line (marker-only lines dropped).
  static std::string one_line(const std::string& msg);
  static std::string joint_list(const Model& m);

 private:
  std::string file_;
};

/// The fields of one registry entry, read through a SpecReader.
struct EntryArgs {
  const SpecReader& reader;
  const EntrySpec& entry;
  const Model& model;
  /// Controllers: the plant's motors and assigned coordinates (null: every joint, no material rows).
  const Actuation* actuation = nullptr;

  bool has(const std::string& k) const { return static_cast<bool>(entry.fields[k]); }
  const SpecValue& value(const std::string& k) const { return entry.fields[k]; }
  std::string key(const std::string& k) const { return entry.key + "." + k; }
  /// A number of the entry with its text (Quantity::number()), for the built object.
  Number number(const std::string& k) const;
  Number number_or(const std::string& k, double dflt) const;
  Number3 numbers3(const std::string& k) const;
  std::string text(const std::string& k) const;
  std::string joint(const std::string& k) const;
  std::string point(const std::string& k) const;
  Vec3 vec3(const std::string& k) const;
  TimeFunctionPtr function(const std::string& k) const;
  Eigen::VectorXd joint_vector(const std::string& k, bool all_required, double dflt) const;
  [[noreturn]] void fail(const std::string& k, const std::string& msg) const;
};

/// One documented key of an entry.
struct KeyDoc {
  std::string name;
  std::string type;          ///< "number", "point", "joint", "function of t", "[x, y, z]", …
  bool required = false;
  std::string default_text;  ///< shown when not required
  std::string doc;
};

struct ConstraintKind {
  std::string name;
  std::string doc;
  std::vector<KeyDoc> keys;  ///< besides name, origin and kind
  ConstraintOrigin default_origin = ConstraintOrigin::Programmed;
  std::function<NewConstraint(const EntryArgs&, ConstraintOrigin)> build;
};

struct ForceKind {
  std::string name;
  std::string doc;
  std::vector<KeyDoc> keys;  ///< besides type and name
  std::function<NewForceElement(const EntryArgs&)> build;
};

/// Makes a controller for a model (the controller keeps a reference to it).
using ControllerFactory = std::function<std::unique_ptr<Controller>(const Model&)>;

struct ControllerKind {
  std::string name;
  std::string doc;
  std::vector<KeyDoc> keys;  ///< besides type
  std::function<ControllerFactory(const EntryArgs&)> build;
};

template <class Kind>
class Registry {
 public:
  explicit Registry(std::string what) : what_(std::move(what)) {}
  void add(Kind k) { kinds_.push_back(std::move(k)); }
  const std::vector<Kind>& entries() const { return kinds_; }
  std::vector<std::string> names() const {
    std::vector<std::string> n;
    for (const auto& k : kinds_) n.push_back(k.name);
    return n;
  }
  const Kind* find(const std::string& name) const {
    for (const auto& k : kinds_)
      if (k.name == name) return &k;
    return nullptr;
  }
  /// Throws Error "unknown WHAT 'name' (did you mean …)".
  const Kind& get(const std::string& name) const { return kinds_[find_name(names(), name, what_)]; }
  const std::string& what() const { return what_; }

 private:
  std::string what_;
  std::vector<Kind> kinds_;
};

const Registry<ConstraintKind>& constraint_kinds();
const Registry<ForceKind>& force_kinds();
const Registry<ControllerKind>& controller_kinds();

/// Allowed keys of an entry (its documented keys plus the common ones).
std::vector<std::string> allowed_keys(const ConstraintKind& k);
std::vector<std::string> allowed_keys(const ForceKind& k);
std::vector<std::string> allowed_keys(const ControllerKind& k);

/// Markdown reference of every registered kind (`refdyn kinds`, docs/scenario.md).
std::string registry_markdown();

}  // namespace refdyn
