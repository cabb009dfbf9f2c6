#pragma once
/// Feasibility of a planned motion (paper section 1.4, first purpose): the speeds,
/// accelerations and generalized forces the joints must deliver, against the model's limits.

#include "refdyn/common/json.hpp"
#include "refdyn/multibody/model.hpp"

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
  JsonValue to_json() const;     ///< the same as a JSON object
  std::string json() const { return to_json().dump(0); }
};

/// Samples t (size K); q, qd, qdd, effort: K vectors of size nq each. `effort` is what the
/// actuators must deliver (for a plan: Trajectory::actuator_effort, i.e. drives and prescribed
/// efforts plus the forces of the programmed constraints; reaction forces of material
/// constraints are carried by the structure and are not checked against effort limits).
FeasibilityReport assess_feasibility(const Model& model, const std::vector<double>& t,
                                     const std::vector<Eigen::VectorXd>& q, const std::vector<Eigen::VectorXd>& qd,
                                     const std::vector<Eigen::VectorXd>& qdd,
                                     const std::vector<Eigen::VectorXd>& effort);

}  // namespace refdyn
