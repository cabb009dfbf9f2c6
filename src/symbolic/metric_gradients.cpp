// metric_gradients (symbolic/sensitivity.hpp): the plan's metrics differentiated in the
// parameters by the chain rule through the sensitivities plan_sensitivity recorded.
#include "refdyn/symbolic/sensitivity.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <vector>

namespace refdyn {

Eigen::MatrixXd metric_gradients(const Problem& problem, const Plan& plan, const PlanSensitivity& s,
                                 const std::vector<Metric>& metrics) {
  const int np = static_cast<int>(s.parameters.size()), n = problem.model.nq;
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(metrics.size()), np);
  const long K = static_cast<long>(std::min(s.t.size(), plan.t.size()));
  if (K == 0) return G;
  const double t0 = problem.integrator.t0, t1 = problem.integrator.t1;
  for (size_t i = 0; i < metrics.size(); ++i) {
    const Metric& mt = metrics[i];
    const long k = std::min(mt.sample, K - 1);
    switch (mt.kind) {
      case MetricKind::TEnd: G.row(i) = s.dt_end; break;
      case MetricKind::PeakSpeed: G.row(i) = mt.sign * s.dx[k].row(n + mt.joint); break;
      case MetricKind::PeakAcceleration: G.row(i) = mt.sign * s.dqdd[k].row(mt.joint); break;
      case MetricKind::PeakEffort: G.row(i) = mt.sign * s.deffort[k].row(mt.joint); break;
      case MetricKind::QMin:
      case MetricKind::QMax:
      case MetricKind::FinalQ: G.row(i) = s.dx[k].row(mt.joint); break;
      case MetricKind::FinalQd: G.row(i) = s.dx[k].row(n + mt.joint); break;
      case MetricKind::MaxResidual:
        if (mt.sample >= 0) G.row(i) = mt.sign * s.dphi[k].row(mt.joint);
        break;
      case MetricKind::EffortEnergy: {
        // trapezoid: Σ ½ Δt_k (|τ_k|² + |τ_{k+1}|²); the intervals move with the samples (on a
        // uniform grid they scale with t1 − t0; with breakpoints each part's with its ends)
        Eigen::RowVectorXd g = Eigen::RowVectorXd::Zero(np);
        const bool uniform = problem.integrator.breakpoints.empty() || s.dt.size() < static_cast<size_t>(K);
        for (long j = 0; j + 1 < K && j + 1 < static_cast<long>(plan.actuator_effort.size()); ++j) {
          const double dt = plan.t[j + 1] - plan.t[j];
          const Eigen::VectorXd &a = plan.actuator_effort[j], &b = plan.actuator_effort[j + 1];
          g += dt * (a.transpose() * s.deffort[j] + b.transpose() * s.deffort[j + 1]);
          if (uniform)
            g += 0.5 * (a.squaredNorm() + b.squaredNorm()) * dt / (t1 - t0) * s.dt_end;
          else
            g += 0.5 * (a.squaredNorm() + b.squaredNorm()) * (s.dt[j + 1] - s.dt[j]);
        }
        G.row(i) = g;
        break;
      }
    }
  }
  return G;
}

}  // namespace refdyn
