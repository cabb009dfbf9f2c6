#pragma once
/// Feasibility of a planned motion (paper section 1.4, first purpose): the speeds,
/// accelerations and generalized forces the joints must deliver, against the model's limits.

#include "refdyn/common/fields.hpp"
#include "refdyn/common/json_fwd.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/simulate/trajectory.hpp"

#include <string>
#include <utility>
#include <vector>

namespace refdyn {

struct FeasibilityViolation {
  std::string joint;
  std::string quantity;     ///< "position", "velocity" or "effort"
  double limit = 0;         ///< the violated bound (lower or upper for position)
  double worst = 0;         ///< the worst value reached
  std::vector<std::pair<double, double>> intervals;  ///< [t_begin, t_end] of each violation
};

struct JointFeasibility {
  std::string joint;
  double q_min = 0, q_max = 0;
  double peak_speed = 0, peak_acceleration = 0, peak_effort = 0;
  double t_peak_speed = 0, t_peak_acceleration = 0, t_peak_effort = 0;
  JointLimits limits;
};

struct FeasibilityReport {
  std::vector<JointFeasibility> joints;
  std::vector<FeasibilityViolation> violations;
  /// False when the planned motion did not reach its end time: a plan that stopped is never
  /// feasible, whatever its samples show (incomplete_reason says why).
  bool complete = true;
  std::string incomplete_reason;
  bool feasible() const { return complete && violations.empty(); }
  std::string text() const;      ///< printable table and list of violations
  JsonValue to_json() const;     ///< the same as a JSON object (the fields below)
  std::string json() const;      ///< feasibility.json: its compact text
};

// The fields of feasibility.json (common/fields.hpp), in its order.
template <>
struct Fields<JointLimits> {
  using S = JointLimits;
  static constexpr auto list() {
    return std::make_tuple(field("lower", &S::lower, "m or rad"), field("upper", &S::upper, "m or rad"),
                           field("velocity", &S::velocity, "m/s or rad/s"), field("effort", &S::effort, "N or N m"));
  }
};
template <>
struct Fields<JointFeasibility> {
  using S = JointFeasibility;
  static constexpr auto list() {
    return std::make_tuple(field("joint", &S::joint), field("q_min", &S::q_min, "m or rad"),
                           field("q_max", &S::q_max, "m or rad"), field("peak_speed", &S::peak_speed, "m/s or rad/s"),
                           field("t_peak_speed", &S::t_peak_speed, "s"),
                           field("peak_acceleration", &S::peak_acceleration, "m/s^2 or rad/s^2"),
                           field("t_peak_acceleration", &S::t_peak_acceleration, "s"),
                           field("peak_effort", &S::peak_effort, "N or N m"), field("t_peak_effort", &S::t_peak_effort, "s"),
                           field("limits", &S::limits));
  }
};
template <>
struct Fields<FeasibilityViolation> {
  using S = FeasibilityViolation;
  static constexpr auto list() {
    return std::make_tuple(field("joint", &S::joint), field("quantity", &S::quantity), field("limit", &S::limit),
                           field("worst", &S::worst), field("intervals", &S::intervals, "s"));
  }
};
template <>
struct Fields<FeasibilityReport> {
  using S = FeasibilityReport;
  static bool feasible(const S& r) { return r.feasible(); }
  static constexpr auto list() {
    return std::make_tuple(derived("feasible", &feasible),
                           field("incomplete_reason", &S::incomplete_reason) | OnlyIf{when::Incomplete},
                           field("joints", &S::joints), field("violations", &S::violations));
  }
};

/// Samples t (size K); q, qd, qdd, effort: K vectors of size nq each. `effort` is what the
/// actuators must deliver (for a plan: Trajectory::actuator_effort, i.e. drives and prescribed
/// efforts plus the forces of the programmed constraints; reaction forces of material
/// constraints are carried by the structure and are not checked against effort limits).
FeasibilityReport assess_feasibility(const Model& model, const std::vector<double>& t,
                                     const SampleSeries& q, const SampleSeries& qd,
                                     const SampleSeries& qdd,
                                     const SampleSeries& effort);

}  // namespace refdyn
