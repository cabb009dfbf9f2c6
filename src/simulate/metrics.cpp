// Named metrics of a plan (simulate/metrics.hpp).
#include "refdyn/simulate/metrics.hpp"

#include "refdyn/common/error.hpp"

#include <algorithm>
#include <cmath>

namespace refdyn {

namespace {

Metric make(std::string name, MetricKind kind, int joint) {
  Metric m;
  m.name = std::move(name);
  m.kind = kind;
  m.joint = joint;
  return m;
}

// max over samples of |series[k][j]| with its sample and sign; NaN samples are skipped.
void peak_abs(const SampleSeries& series, int j, long offset, Metric& m) {
  m.value = 0;
  m.sample = series.empty() ? -1 : 0;
  for (size_t k = 0; k < series.size(); ++k) {
    const double v = series[k][j + offset];
    if (std::isfinite(v) && std::abs(v) > m.value) {
      m.value = std::abs(v);
      m.sample = static_cast<long>(k);
      m.sign = v < 0 ? -1.0 : 1.0;
    }
  }
}

}  // namespace

std::vector<std::string> metric_names(const Model& model, int parts) {
  std::vector<std::string> out{"t_end"};
  for (const char* base : {"peak_speed", "peak_acceleration", "peak_effort", "q_min", "q_max", "final_q", "final_qd"})
    for (int j = 0; j < model.nq; ++j) out.push_back(std::string(base) + "(" + model.joint_name[j] + ")");
  out.push_back("effort_energy");
  out.push_back("max_residual");
  for (int i = 1; i <= parts; ++i)
    for (const char* base : {"peak_speed_part", "peak_effort_part"})
      for (int j = 0; j < model.nq; ++j) out.push_back(std::string(base) + std::to_string(i) + "(" + model.joint_name[j] + ")");
  return out;
}

std::vector<Metric> plan_metrics(const Model& model, const Plan& plan, double residual_from,
                                 const std::vector<double>& part_knots) {
  if (plan.t.empty()) throw Error("the plan has no samples: its metrics are not defined");
  const int n = model.nq;
  const long last = static_cast<long>(plan.t.size()) - 1;
  std::vector<Metric> out;
  Metric te = make("t_end", MetricKind::TEnd, -1);
  te.value = plan.t.back();
  te.sample = last;
  out.push_back(te);
  auto name = [&](const char* base, int j) { return std::string(base) + "(" + model.joint_name[j] + ")"; };
  for (int j = 0; j < n; ++j) {
    Metric m = make(name("peak_speed", j), MetricKind::PeakSpeed, j);
    peak_abs(plan.x, j, n, m);
    out.push_back(m);
  }
  for (int j = 0; j < n; ++j) {
    Metric m = make(name("peak_acceleration", j), MetricKind::PeakAcceleration, j);
    peak_abs(plan.qdd, j, 0, m);
    out.push_back(m);
  }
  for (int j = 0; j < n; ++j) {
    Metric m = make(name("peak_effort", j), MetricKind::PeakEffort, j);
    peak_abs(plan.actuator_effort, j, 0, m);
    out.push_back(m);
  }
  for (int j = 0; j < n; ++j) {
    Metric lo = make(name("q_min", j), MetricKind::QMin, j), hi = make(name("q_max", j), MetricKind::QMax, j);
    lo.value = hi.value = plan.x[0][j];
    lo.sample = hi.sample = 0;
    for (long k = 1; k <= last; ++k) {
      const double v = plan.x[k][j];
      if (v < lo.value) lo.value = v, lo.sample = k;
      if (v > hi.value) hi.value = v, hi.sample = k;
    }
    out.push_back(lo);
    out.push_back(hi);
  }
  for (int j = 0; j < n; ++j) {
    Metric m = make(name("final_q", j), MetricKind::FinalQ, j);
    m.value = plan.x[last][j];
    m.sample = last;
    out.push_back(m);
  }
  for (int j = 0; j < n; ++j) {
    Metric m = make(name("final_qd", j), MetricKind::FinalQd, j);
    m.value = plan.x[last][n + j];
    m.sample = last;
    out.push_back(m);
  }
  Metric energy = make("effort_energy", MetricKind::EffortEnergy, -1);
  for (long k = 0; k < last && !plan.actuator_effort.empty(); ++k)
    energy.value += 0.5 * (plan.t[k + 1] - plan.t[k]) *
                    (plan.actuator_effort[k].squaredNorm() + plan.actuator_effort[k + 1].squaredNorm());
  out.push_back(energy);
  Metric res = make("max_residual", MetricKind::MaxResidual, -1);
  for (long k = 0; k <= last && k < static_cast<long>(plan.phi.size()); ++k) {
    if (plan.t[k] < residual_from) continue;
    for (int r = 0; r < plan.phi[k].size(); ++r) {
      const double v = plan.phi[k][r];
      if (std::isfinite(v) && std::abs(v) > res.value) {
        res.value = std::abs(v);
        res.sample = k;
        res.joint = r;  // the row
        res.sign = v < 0 ? -1.0 : 1.0;
      }
    }
  }
  out.push_back(res);
  // per part of the time law: the samples with t_{i-1} <= t <= t_i (the nearest one if none)
  for (size_t i = 1; i < part_knots.size(); ++i) {
    const double ta = part_knots[i - 1], tb = part_knots[i];
    long k0 = static_cast<long>(std::lower_bound(plan.t.begin(), plan.t.end(), ta) - plan.t.begin());
    long k1 = static_cast<long>(std::upper_bound(plan.t.begin(), plan.t.end(), tb) - plan.t.begin()) - 1;
    if (k0 > k1) {  // no sample inside: the nearest one
      long k = std::min(k0, last);
      if (k > 0 && std::abs(plan.t[k - 1] - 0.5 * (ta + tb)) < std::abs(plan.t[k] - 0.5 * (ta + tb))) --k;
      k0 = k1 = k;
    }
    auto part = [&](const char* base, MetricKind kind, const SampleSeries& series, long offset) {
      for (int j = 0; j < n; ++j) {
        Metric m = make(std::string(base) + std::to_string(i) + "(" + model.joint_name[j] + ")", kind, j);
        m.value = 0;
        m.sample = k0;
        m.sign = 1;
        for (long k = k0; k <= k1 && k < static_cast<long>(series.size()); ++k) {
          const double v = series[static_cast<size_t>(k)][j + offset];
          if (std::isfinite(v) && (k == k0 || std::abs(v) > m.value)) {
            m.value = std::abs(v);
            m.sample = k;
            m.sign = v < 0 ? -1.0 : 1.0;
          }
        }
        out.push_back(m);
      }
    };
    part("peak_speed_part", MetricKind::PeakSpeed, plan.x, n);
    part("peak_effort_part", MetricKind::PeakEffort, plan.actuator_effort, 0);
  }
  return out;
}

}  // namespace refdyn
