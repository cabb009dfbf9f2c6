#pragma once
/// Recorded motions: Trajectory (one entry per output sample), Plan (a solved reference
/// dynamics, with its RK4 stage values for the closed loops) and what a planner records.

#include "refdyn/simulate/integrators.hpp"

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

namespace refdyn {

/// The reference's RK4 stage values, recorded once (see the header comment).
struct ReferenceStages {
  double t0 = 0, h = 0;
  std::vector<double> breakpoints; ///< the grid's breakpoints (IntegratorOptions::breakpoints, Rk4Grid)
  long steps = 0;                  ///< complete steps recorded
  int n = 0;
  std::vector<double> data;        ///< per step, per stage (4), [q̂, q̂̇, q̂̈] (3n doubles)
  const double* stage(long step, int s) const { return data.data() + ((step * 4 + s) * 3 * n); }
  /// Per step, per stage, [ż, λ] (extra_size = nz + m doubles; plans of acceleration-level
  /// problems, else 0): with `data`, everything the sensitivities (symbolic/sensitivity.hpp) need
  /// of a stage, so that they do not evaluate the reference dynamics again.
  int extra_size = 0;
  std::vector<double> extra;
  const double* stage_extra(long step, int s) const { return extra.data() + ((step * 4 + s) * extra_size); }
};

/// A recorded motion, one entry per output sample. What is recorded depends on the recorder:
/// a plan fills the reference-dynamics series (q̈, Φ, Φ̇, λ, Q_c, efforts), a closed loop the
/// tracking series (τ, q̂, q̂̇); series a recorder does not fill stay empty. Names say what the
/// columns of each vector series are; io/trajectory_io.hpp writes any Trajectory as CSV.
struct Trajectory {
  // ---- layout ----
  std::vector<std::string> joints;          ///< q, q̇, q̈, Q_c, efforts, τ, q̂: one per joint
  std::vector<std::string> state_names;     ///< the states after [q; q̇] in x (force elements, controller)
  std::vector<std::string> points;          ///< recorded points (3 columns each: x, y, z in the world)
  std::vector<std::string> constraint_rows; ///< Φ, Φ̇, λ: one per constraint row
  std::vector<char> material_row;           ///< per constraint row: material (1) or programmed (0)
  std::vector<std::string> target_signals;  ///< functions of t prescribed by constraints (record_as)
  std::vector<std::string> force_signals;   ///< quantities of force elements (a drive's ψ_dr, torque)

  // ---- samples ----
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x;           ///< [q; q̇; states]
  std::vector<Eigen::VectorXd> qdd;         ///< q̈ (plans)
  std::vector<Eigen::VectorXd> point_positions;  ///< 3 × points
  std::vector<Eigen::VectorXd> targets, forces;  ///< target_signals, force_signals values
  std::vector<Eigen::VectorXd> phi, phid, lambda;  ///< constraint rows (plans)
  std::vector<Eigen::VectorXd> Qc;          ///< Q_c = M q̈ − F = −Aᵀλ, all rows (plans)
  /// What the actuators must deliver: actuator force elements (drives, efforts) plus the forces
  /// of the programmed constraints (plans). Feasibility checks this against effort limits.
  std::vector<Eigen::VectorXd> actuator_effort;
  /// Reaction forces of the material constraints (pins, rolling without slip): carried by the
  /// structure, not by the actuators (plans; empty when there are no material constraints).
  std::vector<Eigen::VectorXd> reaction_effort;
  std::vector<Eigen::VectorXd> tau, q_ref, qd_ref;  ///< applied τ and the reference (closed loops)

  size_t size() const { return t.size(); }
  int nq() const { return static_cast<int>(joints.size()); }
};

/// A planned motion: the reference dynamics integrated and recorded at every output sample.
struct Plan : Trajectory {
  IntegrationSummary summary;
  ReferenceStages stages;            ///< filled for RK4
};

/// What plan_motion records besides the state (model point indices, e.g. a scenario's outputs).
struct RecordOptions {
  std::vector<int> points;
  /// The plan stops at the first output sample (t >= residual_from) whose constraint residual
  /// max |Phi| exceeds this (or is not a number): that sample is not recorded, the plan ends at
  /// the one before with status ResidualExceeded. Infinity: no check (the library default).
  double residual_tolerance = std::numeric_limits<double>::infinity();
};

}  // namespace refdyn
