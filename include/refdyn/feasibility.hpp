#pragma once
/// Feasibility of a planned motion (paper section 1.4, first purpose): the speeds,
/// accelerations and generalized forces the joints must deliver, against the model's limits.

#include "refdyn/model.hpp"

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
  bool feasible() const { return violations.empty(); }
  std::string text() const;   ///< printable table and list of violations
  std::string json() const;   ///< the same as a JSON object
};

/// Samples t (size K); q, qd, qdd, effort: K vectors of size nq each. `effort` is what the
/// joints must deliver (for a plan: drive/actuator forces + constraint forces Q_c).
FeasibilityReport assess_feasibility(const Model& model, const std::vector<double>& t,
                                     const std::vector<Eigen::VectorXd>& q, const std::vector<Eigen::VectorXd>& qd,
                                     const std::vector<Eigen::VectorXd>& qdd,
                                     const std::vector<Eigen::VectorXd>& effort);

}  // namespace refdyn
