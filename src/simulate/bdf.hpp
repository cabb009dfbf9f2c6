#pragma once
// Implicit integration by CVODE's variable-order BDF (SUNDIALS 6): integrate() with
// IntegratorMethod::BDF lands here (integrators.hpp documents the options and the summary).
#include "refdyn/simulate/integrators.hpp"

namespace refdyn::detail {

IntegrationSummary integrate_bdf(const OdeStageRhs& f, const OdeJacobian& jacobian, Eigen::VectorXd& x,
                                 const IntegratorOptions& options, const OdeObserver& observer,
                                 const OdeProjection& projection);

}  // namespace refdyn::detail
