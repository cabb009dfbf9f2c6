#pragma once
/// What `refdyn check` finds out about a scenario, as data: check_scenario builds the problem,
/// expands its variants, makes its planner and evaluates the reference dynamics once at t0 (every
/// error is thrown before anything is returned), and gathers the model, the constraints and
/// their rows, force elements, the partition, the initial state and residuals, the integrator
/// and the variants into a CheckReport. check_text(report) is the text the command prints (the
/// CLI prints nothing else); Python's refdyn.check returns the report as a dict.

#include "refdyn/common/fields.hpp"
#include "refdyn/scenario/spec.hpp"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace refdyn::io {

/// The parts of the report, in the shapes its JSON (`refdyn check --json`) and Python's dict
/// have (Fields below).
struct CheckRows {
  long total = 0, material = 0, programmed = 0, holonomic = 0, first_order = 0, acceleration = 0, jerk = 0;
};
struct CheckInitialAcceleration {
  std::vector<std::pair<std::string, double>> values;  ///< per joint
  std::string source;                                  ///< "initial.qdd", "consistent_with" or "free"
  std::vector<std::string> consistent_with;
};
struct CheckPartition {
  std::vector<std::string> independent, dependent;
  bool automatic = false;
  double condition = 0;
  bool used_by_solver = true;
};
struct CheckCorrection {
  double dq = 0, q = 0, dqd = 0, qd = 0;
};
struct CheckIntegrator {
  std::string method;
  std::optional<double> step, rtol, atol;  ///< step for rk4, the tolerances for the others
  std::optional<long> max_order;          ///< bdf
  std::optional<double> sample_interval;  ///< dopri5, bdf
  double t0 = 0, t1 = 0;
  std::string stabilization;
  std::optional<double> projection_tolerance;  ///< stabilization other than baumgarte
  std::optional<double> residual_tolerance;    ///< null: the plan does not check it
};
struct CheckPlant {
  std::vector<std::string> actuators, assigned;
  long material_rows = 0;
};

struct CheckReport {
  std::string name;           ///< the scenario's
  std::string file;           ///< as given (a path, or the source name of a text)
  std::string model_summary;  ///< Model::summary(), lines ending in "\n"
  std::vector<std::string> model_notes;  ///< Problem::model_notes (armature read from a URDF, <dynamics>)
  std::vector<std::string> joints;

  struct Constraint {
    std::string name;
    std::string origin;       ///< "material" or "programmed"
    std::string kind;         ///< "holonomic", "first-order", "acceleration-level" or "jerk-level"
    int order = 0;            ///< 0 position, 1 velocity, 2 acceleration, 3 jerk
    bool rheonomic = false;
    int rows = 0;
    std::string description;  ///< Constraint::describe()
  };
  std::vector<Constraint> constraints;
  CheckRows rows;  ///< constraint rows in all and by kind

  std::vector<std::string> force_elements;  ///< names
  std::string planner_description;          ///< Planner::description() (may be empty)
  double t0 = 0;
  /// The planner's state holds q̈ (jerk problems): its initial value, from initial.qdd, consistent
  /// with acceleration rows, or free; none otherwise.
  std::optional<CheckInitialAcceleration> initial_acceleration;
  /// The partition at t0 (io::partition_at_t0); none for a jerk problem.
  std::optional<CheckPartition> partition;
  /// The reference solver ("projection" or "lagrange"); under Lagrange the partition shown is
  /// the one the projection solver would take (partition->used_by_solver false).
  std::string solver;
  /// The initial state was projected onto the constraints: per joint it moved, the correction
  /// and the corrected value; none when no projection was made.
  std::optional<std::vector<std::pair<std::string, CheckCorrection>>> projection;
  /// Residuals of every constraint row at t0 (after the projection): per row, label ("|Phi|", …) → value.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, double>>>> residuals;
  CheckIntegrator integrator;
  long experiments = 0;
  /// The closed loops' plant (docs/scenario.md, "The plant"): its motors, the coordinates the
  /// controllers assign and the material rows kept (empty without experiments).
  CheckPlant plant;
  std::vector<std::string> variants;  ///< every variant's name (empty: no variants: section)
};

/// Checks `spec` (read from `file`, which names it in the report) as `refdyn check` does.
/// Throws Error "FILE:LINE: key: message" for an invalid scenario or variants section, and the
/// planner's errors at t0.
CheckReport check_scenario(const ScenarioSpec& spec, const std::string& file);

/// The text `refdyn check` prints for the report.
std::string check_text(const CheckReport& report);

}  // namespace refdyn::io

namespace refdyn {
// The report's fields (common/fields.hpp): `refdyn check --json` (sink::Json) and Python's
// refdyn.check (sink::Python; also the text the command prints).
template <>
struct Fields<io::CheckReport::Constraint> {
  using S = io::CheckReport::Constraint;
  static std::string label(const S& c) { return order_label(c.order); }
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("name", &S::name, "", in), field("origin", &S::origin, "", in),
                           field("kind", &S::kind, "", in), field("order", &S::order, "", in),
                           derived("order_label", &label, "", in), field("rheonomic", &S::rheonomic, "", in),
                           field("rows", &S::rows, "", in), field("description", &S::description, "", in));
  }
};
template <>
struct Fields<io::CheckRows> {
  using S = io::CheckRows;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("total", &S::total, "", in), field("material", &S::material, "", in),
                           field("programmed", &S::programmed, "", in), field("holonomic", &S::holonomic, "", in),
                           field("first_order", &S::first_order, "", in),
                           field("acceleration", &S::acceleration, "", in), field("jerk", &S::jerk, "", in));
  }
};
template <>
struct Fields<io::CheckInitialAcceleration> {
  using S = io::CheckInitialAcceleration;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("values", &S::values, "m/s^2 or rad/s^2", in), field("source", &S::source, "", in),
                           field("consistent_with", &S::consistent_with, "", in));
  }
};
template <>
struct Fields<io::CheckPartition> {
  using S = io::CheckPartition;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("independent", &S::independent, "", in), field("dependent", &S::dependent, "", in),
                           field("automatic", &S::automatic, "", in), field("condition", &S::condition, "", in),
                           field("used_by_solver", &S::used_by_solver, "", in));
  }
};
template <>
struct Fields<io::CheckCorrection> {
  using S = io::CheckCorrection;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("dq", &S::dq, "m or rad", in), field("q", &S::q, "m or rad", in),
                           field("dqd", &S::dqd, "m/s or rad/s", in), field("qd", &S::qd, "m/s or rad/s", in));
  }
};
template <>
struct Fields<io::CheckIntegrator> {
  using S = io::CheckIntegrator;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("method", &S::method, "", in), field("step", &S::step, "s", in) | OmitIfEmpty{},
                           field("rtol", &S::rtol, "", in) | OmitIfEmpty{}, field("atol", &S::atol, "", in) | OmitIfEmpty{},
                           field("max_order", &S::max_order, "", in) | OmitIfEmpty{},
                           field("sample_interval", &S::sample_interval, "s", in) | OmitIfEmpty{},
                           field("t0", &S::t0, "s", in), field("t1", &S::t1, "s", in),
                           field("stabilization", &S::stabilization, "", in),
                           field("projection_tolerance", &S::projection_tolerance, "", in) | OmitIfEmpty{},
                           field("residual_tolerance", &S::residual_tolerance, "", in));
  }
};
template <>
struct Fields<io::CheckPlant> {
  using S = io::CheckPlant;
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(field("actuators", &S::actuators, "", in), field("assigned", &S::assigned, "", in),
                           field("material_rows", &S::material_rows, "", in));
  }
};
template <>
struct Fields<io::CheckReport> {
  using S = io::CheckReport;
  static bool valid(const S&) { return true; }  // an invalid scenario is an error, never a report
  static std::string text(const S& r) { return io::check_text(r); }
  static constexpr unsigned in = sink::Json | sink::Python;
  static constexpr auto list() {
    return std::make_tuple(
        field("scenario", &S::name, "", in), field("file", &S::file, "", in), derived("valid", &valid, "", in),
        field("model", &S::model_summary, "", in), field("model_notes", &S::model_notes, "", in),
        field("joints", &S::joints, "", in), field("constraints", &S::constraints, "", in),
        field("rows", &S::rows, "", in), field("force_elements", &S::force_elements, "", in),
        field("planner", &S::planner_description, "", in), field("t0", &S::t0, "s", in),
        field("initial_acceleration", &S::initial_acceleration, "", in), field("partition", &S::partition, "", in),
        field("projection", &S::projection, "", in), field("residuals", &S::residuals, "", in),
        field("integrator", &S::integrator, "", in), field("experiments", &S::experiments, "", in),
        field("plant", &S::plant, "", in), field("variants", &S::variants, "", in),
        derived("text", &text, "", sink::Python));
  }
};
}  // namespace refdyn
