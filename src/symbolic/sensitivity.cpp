// Forward sensitivities of a plan (symbolic/sensitivity.hpp). Being written: this first version
// only states that they are not available yet.
#include "refdyn/symbolic/sensitivity.hpp"

#include "refdyn/common/error.hpp"

namespace refdyn {

PlanSensitivity plan_sensitivity(const Problem&, const Plan&, const SensitivityOptions&) {
  throw Error("sensitivities are not available in this build yet");
}

Eigen::MatrixXd metric_gradients(const Problem&, const Plan&, const PlanSensitivity&, const std::vector<Metric>&) {
  throw Error("sensitivities are not available in this build yet");
}

}  // namespace refdyn
