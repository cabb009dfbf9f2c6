#pragma once
/// Scenario specification: what a scenario file says, as plain structs with defaults and no
/// numerics (like Drake's scenario structs). The YAML layer (io/scenario.hpp) fills these;
/// build_problem (problem.hpp) turns them into a Problem: it evaluates numbers, which may be
/// expressions of the parameters ("0.5*cos(45*deg)"), binds names to indices, builds the
/// model, constraints, forces and controllers through their registries (registry.hpp), and
/// checks the initial state. Every value keeps where it was written (file, line, key) so that
/// any error found later still points at the text.

#include "refdyn/model.hpp"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace refdyn {

/// Where a value was written. line is 1-based; 0 when unknown (e.g. a missing key).
struct SourceLocation {
  std::string file;
  int line = 0;
};

/// A value as written: nothing, a scalar text, a list or a mapping (entries in file order).
/// Numbers stay text until build_problem evaluates them.
struct SpecValue {
  enum class Kind { Null, Scalar, List, Map };
  struct Entry;
  Kind kind = Kind::Null;
  std::string text;              ///< Scalar
  std::vector<SpecValue> items;  ///< List
  std::vector<Entry> entries;    ///< Map, in file order, keys unique
  SourceLocation where;          ///< where the value starts (for a missing key: nothing)

  bool is_null() const { return kind == Kind::Null; }
  bool is_scalar() const { return kind == Kind::Scalar; }
  bool is_list() const { return kind == Kind::List; }
  bool is_map() const { return kind == Kind::Map; }
  /// Present (not Null).
  explicit operator bool() const { return kind != Kind::Null; }
  /// Map lookup; a Null value (with no location) when the key is absent or this is no map.
  const SpecValue& operator[](const std::string& key) const;
  /// List element; a Null value when out of range or this is no list.
  const SpecValue& operator[](size_t i) const;
  /// Items of a list or entries of a map.
  size_t size() const;
  /// Location of the key `key` of this map (the key's own line), else this value's location.
  SourceLocation key_location(const std::string& key) const;
  /// "nothing", "'text'", "a list" or "a mapping": for "got …" in messages.
  std::string describe() const;

  static SpecValue scalar(std::string text, SourceLocation where = {});
};

struct SpecValue::Entry {
  std::string key;
  int key_line = 0;
  SpecValue value;
};

inline size_t SpecValue::size() const { return is_list() ? items.size() : is_map() ? entries.size() : 0; }

/// One entry of an extensible section: a constraint, a force element or a controller. `kind`
/// selects the registry entry (registry.hpp) that owns the other keys of `fields`.
struct EntrySpec {
  std::string kind;        ///< e.g. "point_on_ellipse", "expression", "lugre", "computed_torque_pd"
  std::string name;        ///< constraints: their unique name; force elements: an optional label
  std::string key;         ///< key path for messages, e.g. "constraints.ellipse" or "forces[1]"
  SpecValue fields;        ///< the entry's mapping as written (kind/type/name included)
};

/// A URDF <mimic> joint: q_joint = multiplier * q_leader + offset (becomes a material coupling).
struct MimicSpec {
  std::string joint, leader;
  double multiplier = 1.0, offset = 0.0;
};

struct ModelSpec {
  /// dh: or links: as written (numbers may be expressions; evaluated by build_problem), with
  /// name, gravity, base and points.
  SpecValue value;
  /// A model read from URDF by the I/O layer (model.urdf), with its <mimic> couplings.
  std::optional<ModelDescription> urdf;
  std::vector<MimicSpec> mimics;
};

struct PartitionSpec {
  bool automatic = true;                   ///< `auto` or absent
  std::vector<std::string> independent;    ///< joint names (n − m), when not automatic
  SpecValue independent_value;             ///< the list as written (for messages)
  SpecValue automatic_switch, max_condition;
  SpecValue value;                         ///< the section as written (null if absent)
};

struct BaumgarteSpec {
  SpecValue alpha, beta, beta_first_order;
  SpecValue value;
  SpecValue kappa;  ///< jerk problems: gain on the projected dynamics residual
};

struct InitialSpec {
  SpecValue q, qd;
  bool project = false;                    ///< consistency: project (else check)
  SpecValue tolerance;
  SpecValue value;
  SpecValue qdd;                           ///< jerk problems: initial acceleration (hint)
};

struct IntegratorSpec {
  std::string method = "rk4";              ///< rk4 | dopri5
  SpecValue step, t0, t1, rtol, atol, output_interval, min_step, residual_from, max_steps;
  SpecValue value;
};

struct ExperimentSpec {
  std::string name;                        ///< may contain {param}
  bool named = false;
  std::string key;                         ///< "experiments[i]"
  std::string sweep_parameter;             ///< empty: no sweep
  std::vector<SpecValue> sweep_values;
  SpecValue sweep;                         ///< as written
  SpecValue initial_q, initial_qd;
  std::optional<std::vector<EntrySpec>> plant_forces;  ///< absent: the top-level plant_forces
  std::optional<EntrySpec> controller;                 ///< absent: the top-level controller
  SpecValue value;
};

struct ScenarioSpec {
  std::string file;                        ///< source name used in messages
  std::string name;
  std::vector<std::pair<std::string, SpecValue>> parameters;  ///< in order; each may use the previous
  ModelSpec model;
  std::vector<EntrySpec> constraints;
  SpecValue constraints_value;
  std::vector<EntrySpec> forces;
  std::optional<std::vector<EntrySpec>> plant_forces;
  PartitionSpec partition;
  BaumgarteSpec baumgarte;
  std::string solver = "auto";             ///< projection | lagrange | auto (by size, resolved by build_problem)
  bool paper_literal_forces = false;
  InitialSpec initial;
  IntegratorSpec integrator;
  std::optional<EntrySpec> controller;
  SpecValue effort_limit;
  std::vector<ExperimentSpec> experiments;
  SpecValue experiments_value;
  std::optional<std::vector<SpecValue>> output_points;  ///< absent: every model point
  SpecValue limits;                        ///< {max_steps, max_samples, max_runs} as written
  SpecValue root;                          ///< the whole file as written (for messages)
};

}  // namespace refdyn
