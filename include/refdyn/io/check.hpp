#pragma once
/// What `refdyn check` finds out about a scenario, as data: check_scenario builds the problem,
/// expands its variants, makes its planner and evaluates the reference dynamics once at t0 (every
/// error is thrown before anything is returned), and gathers the model, the constraints and
/// their rows, force elements, the partition, the initial state and residuals, the integrator
/// and the variants into a CheckReport. check_text(report) is the text the command prints (the
/// CLI prints nothing else); Python's refdyn.check returns the report as a dict.

#include "refdyn/scenario/spec.hpp"

#include <string>
#include <vector>

namespace refdyn::io {

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
  int rows = 0;  ///< constraint rows in all
  int material_rows = 0, programmed_rows = 0;
  int holonomic_rows = 0, first_order_rows = 0, acceleration_rows = 0, jerk_rows = 0;

  std::vector<std::string> force_elements;  ///< names
  std::string planner_description;          ///< Planner::description() (may be empty)

  double t0 = 0;
  /// The planner's state holds q̈ (jerk problems): its initial value, from initial.qdd or free.
  bool has_initial_acceleration = false;
  bool initial_acceleration_given = false;
  /// "initial.qdd" (a hint per joint), "consistent_with" (jerk rows made with differentiate: true
  /// satisfy their acceleration rows: initial_acceleration_rows) or "free".
  std::string initial_acceleration_source;
  std::vector<std::string> initial_acceleration_rows;
  std::vector<double> initial_acceleration;  ///< per joint

  /// The closed loops' plant (docs/scenario.md, "The plant"): its motors, its material rows and
  /// the coordinates the controllers assign (joint names; empty without experiments).
  std::vector<std::string> actuators, plant_independent;
  int plant_material_rows = 0;

  bool has_partition = false;
  std::vector<std::string> independent, dependent;  ///< joint names
  bool automatic_partition = false;  ///< chosen at t0 (partition.independent: auto)
  double condition = 0;  ///< cond(K_dc) at t0, 1-norm (io::partition_at_t0)
  /// The reference solver ("projection" or "lagrange") and whether it uses the partition: the
  /// Lagrange (KKT) solver does not; the partition shown is then the projection solver's.
  std::string solver;
  bool partition_used = true;

  /// The initial state was projected onto the constraints; the joints it moved.
  bool projected = false;
  struct Correction {
    std::string joint;
    double dq = 0, q = 0, dqd = 0, qd = 0;  ///< correction and corrected value
  };
  std::vector<Correction> corrections;

  /// Residuals of every constraint row at t0 (after the projection): one label per kind of
  /// residual ("|Phi|", …) and per row one value for each.
  std::vector<std::string> residual_labels;
  struct RowResiduals {
    std::string row;
    std::vector<double> values;
  };
  std::vector<RowResiduals> residuals;

  // the integrator
  std::string method;  ///< "rk4", "dopri5", "bdf"
  double step = 0, rtol = 0, atol = 0, sample_interval = 0, t1 = 0;
  int max_order = 0;            ///< BDF
  std::string stabilization;    ///< "baumgarte", "projection" or "both"
  double projection_tolerance = 0;
  bool checks_residual = false;  ///< the plan stops where max |Phi| > residual_tolerance
  double residual_tolerance = 0;

  long experiments = 0;
  std::vector<std::string> variants;  ///< every variant's name (empty: no variants: section)
};

/// Checks `spec` (read from `file`, which names it in the report) as `refdyn check` does.
/// Throws Error "FILE:LINE: key: message" for an invalid scenario or variants section, and the
/// planner's errors at t0.
CheckReport check_scenario(const ScenarioSpec& spec, const std::string& file);

/// The text `refdyn check` prints for the report.
std::string check_text(const CheckReport& report);

}  // namespace refdyn::io
