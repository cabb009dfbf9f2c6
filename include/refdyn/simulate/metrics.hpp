#pragma once
/// Named metrics of a plan: the numbers an objective or a constraint of `refdyn optimize`
/// speaks of (docs/optimize.md), each with the sample it is taken at, so that its derivative
/// with respect to a parameter (symbolic/sensitivity.hpp) is the derivative of that sample's
/// quantity (a maximum is differentiated at its argmax: the envelope rule, exact wherever the
/// argmax is unique).
///
///   t_end                  the plan's final time [s]
///   peak_speed(j)          max over samples of |q̇_j|            (feasibility.json's peak_speed)
///   peak_acceleration(j)   max |q̈_j|
///   peak_effort(j)         max |τ_j|, τ the actuator effort      (feasibility.json's peak_effort)
///   q_min(j), q_max(j)     the extreme values of q_j
///   final_q(j), final_qd(j) q_j and q̇_j at the last sample
///   effort_energy          ∫ τᵀτ dt (trapezoid over the samples) [N² m² s]
///   max_residual           the largest constraint residual max |Φ| after residual_from
/// With the knot times t_0 < t_1 < … < t_K of a time law (Problem::time_law_knots), per part
/// i = 1…K the peaks over the samples with t_{i−1} ≤ t ≤ t_i (the nearest sample when the part
/// holds none):
///   peak_speed_part<i>(j), peak_effort_part<i>(j)   e.g. peak_effort_part3(q1)
#include "refdyn/simulate/trajectory.hpp"
#include "refdyn/multibody/model.hpp"

#include <string>
#include <vector>

namespace refdyn {

enum class MetricKind {
  TEnd, PeakSpeed, PeakAcceleration, PeakEffort, QMin, QMax, FinalQ, FinalQd, EffortEnergy, MaxResidual
};

struct Metric {
  std::string name;     ///< as written in expressions: "peak_effort(psi2)", "t_end"
  MetricKind kind = MetricKind::TEnd;
  int joint = -1;       ///< the joint index of per-joint metrics; max_residual: the row; −1 otherwise
  double value = 0;
  long sample = -1;     ///< the sample the value is taken at (argmax / argmin / last); −1 for integrals
  double sign = 1;      ///< peaks of |·|: the sign of the quantity at `sample`
};

/// Every metric of `plan` (all kinds, every joint of `model`), in the order above per joint.
/// `residual_from`: the plan's residual window. Throws Error for an empty plan.
/// `part_knots`: the time law's knot times (empty: no per-part metrics).
std::vector<Metric> plan_metrics(const Model& model, const Plan& plan, double residual_from = 0.0,
                                 const std::vector<double>& part_knots = {});

/// The metric names plan_metrics gives for `model` (for "did you mean" before any plan), with
/// the per-part metrics of `parts` parts.
std::vector<std::string> metric_names(const Model& model, int parts = 0);

}  // namespace refdyn
