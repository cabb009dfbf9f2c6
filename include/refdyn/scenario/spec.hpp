#pragma once
/// Scenario specification: what a scenario file says, as plain structs with defaults and no
/// numerics (like Drake's scenario structs). The YAML layer (io/scenario.hpp) fills these;
/// build_problem (problem.hpp) turns them into a Problem: it evaluates numbers, which may be
/// expressions of the parameters ("0.5*cos(45*deg)"), binds names to indices, builds the
/// model, constraints, forces and controllers through their registries (registry.hpp), and
/// checks the initial state. Every value keeps where it was written (file, line, key) so that
/// any error found later still points at the text.

#include "refdyn/expression/symbolic_form.hpp"
#include "refdyn/multibody/model.hpp"

#include <array>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace refdyn {

/// Where a value was written. line and column are 1-based; 0 when unknown (e.g. a missing key).
/// The column is where the value's text starts (a quote for a quoted scalar, `[` for a flow
/// list): optimized.yaml rewrites values in place from it (optimize/optimize.hpp).
struct SourceLocation {
  std::string file;
  int line = 0;
  int column = 0;
};

/// A number of the scenario as the reader made it (SpecReader::quantity): its value, the text
/// as written (`0.3`, `m2 * 0.5`, a parameter name) and where it was written. The built objects
/// get number(): the value, with the text when it is an expression (the code generator writes
/// the text, so the equations keep the scenario's names); messages get text and where.
struct Quantity {
  double value = 0.0;
  std::string text;
  SourceLocation where;
  bool literal = true;  ///< the text is a plain number (no parameter, no operator)
  Number number() const { return literal ? Number(value) : Number(value, text); }
};

/// The numbers of a `model:` section written as dh: or links:, as the reader read them (every
/// one a Quantity: value, text, where), in the section's structure: what the code generator
/// (symbolic/model.cpp) builds its symbolic bodies from, so the parameters stay symbols.
struct ModelNumbers {
  using Vec = std::array<Quantity, 3>;
  struct Pose {
    std::optional<Vec> xyz, rpy;
  };
  struct Link {
    std::string name;       ///< the link's name
    int parent = -1;        ///< index into links; −1: the base
    JointType type = JointType::Revolute;
    std::optional<Quantity> theta, d, a, alpha;  ///< dh:
    Pose origin, link_offset;                    ///< links:
    std::optional<Quantity> offset;              ///< links:
    std::optional<Quantity> mass;
    std::optional<Vec> com;
    std::vector<Quantity> inertia;  ///< as written: 3 (diagonal), 6 (Ixx Iyy Izz Ixy Ixz Iyz) or 9 (3x3, rows)
    bool inertia_matrix = false;    ///< the 9 values were written as a 3x3 list
    std::optional<Quantity> armature;  ///< the joint's armature (links:/dh: key or model.armature)
  };
  struct Point {
    std::string name, link;
    std::optional<Vec> position;
  };
  bool dh = false;        ///< dh: (else links:)
  bool standard = true;   ///< dh: convention
  std::vector<Link> links;
  Pose base;
  std::vector<Point> points;  ///< in the order written (a later one replaces one of the same name)
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
  /// What the reader of the model says about it, one line each (a URDF's armature from Drake's
  /// rotor tags; its <dynamics> ignored or turned into force elements): `refdyn check` prints them.
  std::vector<std::string> notes;
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

/// `stabilization: baumgarte | projection | both`, or `{method, tolerance, max_iterations}`.
struct StabilizationSpec {
  std::string method = "baumgarte";
  SpecValue tolerance, max_iterations;
  SpecValue value;                         ///< as written (null: not given)
};

struct InitialSpec {
  SpecValue q, qd;
  bool project = false;                    ///< consistency: project (else check)
  SpecValue tolerance;
  SpecValue value;
  SpecValue qdd;                           ///< jerk problems: initial acceleration (hint)
};

struct IntegratorSpec {
  std::string method = "rk4";              ///< rk4 | dopri5 | bdf
  SpecValue step, t0, t1, rtol, atol, output_interval, min_step, residual_from, residual_tolerance, max_order;
  SpecValue value;
};

/// One random parameter of a Monte Carlo experiment: `name: {normal: {mean: a, std: b}}` or
/// `name: {uniform: {low: a, high: b}}` (docs/scenario.md, "experiments").
struct DistributionSpec {
  std::string parameter;
  std::string kind;                        ///< "normal" | "uniform"
  SpecValue a, b;                          ///< normal: mean, std; uniform: low, high (as written)
  SpecValue value;                         ///< the parameter's mapping as written
};

/// `monte_carlo: {samples, seed, distributions}`: `samples` runs whose parameters are drawn
/// from std::mt19937_64 seeded with `seed`, per sample in the order of `distributions`.
struct MonteCarloSpec {
  SpecValue samples, seed;                 ///< as written (build_problem evaluates and checks them)
  std::vector<DistributionSpec> distributions;  ///< in the order written: the draw order
  SpecValue value;
};

/// One entry of `experiments:`. At most one of sweep, grid and monte_carlo is given; each
/// expands the experiment into several runs (build_problem).
struct ExperimentSpec {
  std::string name;                        ///< may contain {param} (and {sample})
  bool named = false;
  std::string key;                         ///< "experiments[i]"
  std::string sweep_parameter;             ///< empty: no sweep
  std::vector<SpecValue> sweep_values;
  SpecValue sweep;                         ///< as written
  /// grid: {p1: [values], p2: [values], …}: one run per combination, the first parameter
  /// varying slowest (row-major). Empty: no grid.
  std::vector<std::pair<std::string, std::vector<SpecValue>>> grid;
  SpecValue grid_value;                    ///< as written
  std::optional<MonteCarloSpec> monte_carlo;
  SpecValue initial_q, initial_qd;
  std::optional<std::vector<EntrySpec>> plant_forces;  ///< absent: the top-level plant_forces
  std::optional<EntrySpec> controller;                 ///< absent: the top-level controller
  SpecValue value;
};

/// `variants:` — a family of tasks: the same scenario with some parameters set to other values
/// (io/variants.hpp, docs/sweeps.md). One of sweep (one parameter), grid and monte_carlo.
struct VariantsSpec {
  std::string name;                        ///< folder name template with {param} (and {sample})
  bool named = false;
  /// sweep / grid: parameter → values; one run per combination, the first parameter slowest.
  std::vector<std::pair<std::string, std::vector<SpecValue>>> grid;
  SpecValue value;                         ///< the section as written
};

/// `optimize:` — the task parameters `refdyn optimize` chooses (optimize/optimize.hpp,
/// docs/optimize.md), as written; the optimize layer checks names, bounds and expressions.
struct OptimizeVariableSpec {
  std::string name;
  std::string key;                         ///< "optimize.variables[i]"
  SpecValue lower, upper, start;           ///< as written (start: absent = the parameter's value)
  SpecValue value;
};

struct OptimizeBoundSpec {
  std::string expression;                  ///< an expression of metrics, variables and parameters
  std::string key;                         ///< "optimize.constraints.bounds[i]"
  SpecValue lower, upper;                  ///< at least one of them
  SpecValue value;
};

struct OptimizeSpec {
  std::vector<OptimizeVariableSpec> variables;
  bool maximize = false;                   ///< objective: {maximize: EXPR} (else minimize)
  std::string objective;                   ///< the expression as written
  SpecValue objective_value;               ///< the expression's value (for its location)
  bool feasible = false;                   ///< constraints.feasible
  std::vector<OptimizeBoundSpec> bounds;
  std::string method = "slsqp";            ///< slsqp | mma | cobyla | bobyqa
  SpecValue method_value;
  SpecValue tolerance_x, tolerance_f, budget;  ///< as written (absent: defaults)
  SpecValue value;                         ///< the section as written
};

struct ScenarioSpec {
  std::string file;                        ///< source name used in messages
  std::string name;
  /// In order; each may use the previous. A value is a number or an expression, or a list of
  /// them (a list parameter, e.g. knot speeds `v: [0.5, 0.5, …]`: used whole by name, as in
  /// `time_law: {knot_speeds: v}`, and as one vector variable by optimize:).
  std::vector<std::pair<std::string, SpecValue>> parameters;
  /// Parameters set to a number by a variant (io/variants.hpp): the value is used as it is (not
  /// written back as text and evaluated again); text and where (the parameter's) for messages.
  std::map<std::string, Quantity> parameter_values;
  /// List parameters set to numbers (an optimize: candidate's vector variable), one per element.
  std::map<std::string, std::vector<double>> list_values;
  ModelSpec model;
  std::vector<EntrySpec> constraints;
  SpecValue constraints_value;
  std::vector<EntrySpec> forces;
  std::optional<std::vector<EntrySpec>> plant_forces;
  PartitionSpec partition;
  BaumgarteSpec baumgarte;
  StabilizationSpec stabilization;
  std::string solver = "auto";             ///< projection | lagrange | auto (by size, resolved by build_problem)
  bool paper_literal_forces = false;
  InitialSpec initial;
  IntegratorSpec integrator;
  std::optional<EntrySpec> controller;
  SpecValue effort_limit;
  SpecValue actuators;                     ///< [joint, …] with a motor (null: every joint)
  std::vector<ExperimentSpec> experiments;
  SpecValue experiments_value;
  std::optional<std::vector<SpecValue>> output_points;  ///< absent: every model point
  std::optional<VariantsSpec> variants;    ///< absent: one scenario
  std::optional<OptimizeSpec> optimize;    ///< absent: nothing to optimize
  SpecValue limits;                        ///< {max_steps, max_samples, max_runs} as written
  /// `time_law: {task_duration, segments}` as written (null: none); build_problem makes the
  /// TimeLaw (expression/time_law.hpp) that retimes every function of time.
  SpecValue time_law;
  SpecValue root;                          ///< the whole file as written (for messages)
};

}  // namespace refdyn
