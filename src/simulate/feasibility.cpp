#include "refdyn/simulate/feasibility.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/fields_json.hpp"
#include "refdyn/common/text.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace refdyn {

namespace {
std::string num(double x) {
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", x);
  return b;
}
}  // namespace

FeasibilityReport assess_feasibility(const Model& model, const std::vector<double>& t,
                                     const SampleSeries& q, const SampleSeries& qd,
                                     const SampleSeries& qdd,
                                     const SampleSeries& effort) {
  const size_t K = t.size();
  if (q.size() != K || qd.size() != K || qdd.size() != K || effort.size() != K)
    throw Error(expected_got("feasibility samples", std::to_string(K) + " of each of q, qd, qdd, effort",
                             std::to_string(q.size()) + ", " + std::to_string(qd.size()) + ", " +
                                 std::to_string(qdd.size()) + ", " + std::to_string(effort.size())));
  if (K == 0) throw Error("feasibility: expected samples, got none");
  const int n = model.nv;
  FeasibilityReport rep;
  for (int j = 0; j < n; ++j) {
    JointFeasibility jf;
    jf.joint = model.joint_name[j];
    jf.limits = model.limits[j];
    jf.q_min = jf.q_max = q[0][j];
    for (size_t k = 0; k < K; ++k) {
      jf.q_min = std::min(jf.q_min, q[k][j]);
      jf.q_max = std::max(jf.q_max, q[k][j]);
      if (std::abs(qd[k][j]) > jf.peak_speed) jf.peak_speed = std::abs(qd[k][j]), jf.t_peak_speed = t[k];
      if (std::abs(qdd[k][j]) > jf.peak_acceleration)
        jf.peak_acceleration = std::abs(qdd[k][j]), jf.t_peak_acceleration = t[k];
      if (std::abs(effort[k][j]) > jf.peak_effort) jf.peak_effort = std::abs(effort[k][j]), jf.t_peak_effort = t[k];
    }
    // Violations with their time intervals.
    struct Check {
      const char* what;
      double limit;
      bool upper;
      const SampleSeries* v;
      bool absolute;
    };
    const Check checks[] = {{"position", jf.limits.upper, true, &q, false},
                            {"position", jf.limits.lower, false, &q, false},
                            {"velocity", jf.limits.velocity, true, &qd, true},
                            {"effort", jf.limits.effort, true, &effort, true}};
    for (const Check& c : checks) {
      if (!std::isfinite(c.limit)) continue;
      FeasibilityViolation v{jf.joint, c.what, c.limit, c.upper ? -INFINITY : INFINITY, {}};
      bool in = false;
      for (size_t k = 0; k < K; ++k) {
        const double x = c.absolute ? std::abs((*c.v)[k][j]) : (*c.v)[k][j];
        const bool bad = c.upper ? x > c.limit : x < c.limit;
        if (bad) {
          v.worst = c.upper ? std::max(v.worst, x) : std::min(v.worst, x);
          if (!in) v.intervals.push_back({t[k], t[k]});
          v.intervals.back().second = t[k];
        }
        in = bad;
      }
      if (!v.intervals.empty()) rep.violations.push_back(std::move(v));
    }
    rep.joints.push_back(jf);
  }
  return rep;
}

std::string FeasibilityReport::text() const {
  std::ostringstream os;
  os << "feasibility of the planned motion\n";
  os << "  joint      q range                 peak |qd|  (limit)      peak |qdd|   peak |effort|  (limit)\n";
  for (const auto& j : joints) {
    char line[256];
    std::snprintf(line, sizeof line, "  %-8s  [%10.5g, %10.5g]  %10.5g (%8s)  %10.5g   %10.5g   (%8s)\n", j.joint.c_str(),
                  j.q_min, j.q_max, j.peak_speed, num(j.limits.velocity).c_str(), j.peak_acceleration, j.peak_effort,
                  num(j.limits.effort).c_str());
    os << line;
  }
  if (!complete) {
    os << "  NOT feasible: the plan did not reach its end (" << incomplete_reason << ")\n";
  }
  if (violations.empty()) {
    if (complete) os << "  feasible: no limit is violated\n";
  } else {
    os << "  NOT feasible: " << violations.size() << " violation(s)\n";
    for (const auto& v : violations) {
      os << "    " << v.joint << " " << v.quantity << " limit " << num(v.limit) << " exceeded (worst " << num(v.worst)
         << ") during";
      for (const auto& iv : v.intervals) os << " [" << num(iv.first) << ", " << num(iv.second) << "] s";
      os << "\n";
    }
  }
  return os.str();
}

JsonValue FeasibilityReport::to_json() const {
  FieldContext c;
  if (!complete) c.holds |= when::Incomplete;
  return refdyn::to_json(*this, c);
}

std::string FeasibilityReport::json() const { return json_text(to_json(), 0); }

}  // namespace refdyn
