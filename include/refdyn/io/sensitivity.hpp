#pragma once
/// The files of `refdyn plan --sensitivity p1,p2` (docs/sensitivity.md):
///   sensitivity.csv   one row per plan sample: t, then for each parameter p the derivatives
///                     dq_<j>/d<p>, dqd_<j>/d<p>, d<state>/d<p>, dqdd_<j>/d<p>,
///                     drequired_<j>/d<p> (the actuator effort), dphi_<row>/d<p>
///   sensitivity.json  the parameters and their values, every plan metric with its value, the
///                     sample it is taken at and its gradient {p: dJ/dp}, and the wall time
#include "refdyn/common/json_fwd.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/simulate/metrics.hpp"
#include "refdyn/symbolic/sensitivity.hpp"

#include <Eigen/Core>
#include <vector>

namespace refdyn::io {

CsvTable sensitivity_table(const Problem& problem, const Plan& plan, const PlanSensitivity& s);
/// `gradients`: metric_gradients(problem, plan, s, metrics).
JsonValue sensitivity_json(const Problem& problem, const PlanSensitivity& s, const std::vector<Metric>& metrics,
                           const Eigen::MatrixXd& gradients);

}  // namespace refdyn::io
