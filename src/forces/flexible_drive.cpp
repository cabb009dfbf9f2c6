// flexible_drive: the paper's flexible drive (4.6), τ = s (ψ_dr(t) − q_j) + d (ψ̇_dr(t) − q̇_j),
// written once (torque_law); apply (the paper study's arithmetic), apply_dual, ∂Q/∂q̇ and the jerk
// level's rate are its instantiations (ForceLaw), the recorded torque signal too.
#include "element_support.hpp"

#include <cmath>

namespace refdyn {

FlexibleDrive::FlexibleDrive(const Model& model, const std::string& joint, FlexibleDriveParams p,
                             TimeFunctionPtr profile)
    : j_(model.joint_index(joint)), joint_name_(joint), p_(p), profile_(std::move(profile)) {
  using force_detail::need;
  need(std::isfinite(p.stiffness.value) && p.stiffness >= 0, "flexible drive stiffness", "a finite value >= 0", p.stiffness);
  need(std::isfinite(p.damping.value) && p.damping >= 0, "flexible drive damping", "a finite value >= 0", p.damping);
  if (!profile_) throw Error("flexible drive: expected a displacement profile, got none");
}

template <class S>
S FlexibleDrive::torque_law(const S& t, const S& qj, const S& qdj) const {
  const auto psi = time_value(*profile_, t);
  return param<S>(p_.stiffness) * (psi.f - qj) + param<S>(p_.damping) * (psi.df - qdj);
}

template <class S>
void FlexibleDrive::law(const S& t, const S* q, const S* qd, const S*, S* Q, S*) const {
  Q[j_] += torque_law(t, q[j_], qd[j_]);
}
REFDYN_INSTANTIATE_FORCE_LAW(FlexibleDrive);

double FlexibleDrive::torque(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) const {
  return torque_law(t, q[j_], qd[j_]);
}

std::vector<std::string> FlexibleDrive::signal_names() const {
  const std::string suffix = label.empty() ? "" : "_" + label;
  return {"psi_dr" + suffix, "tau_drive" + suffix};
}

void FlexibleDrive::signals(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double*,
                            double* out) const {
  out[0] = profile_->eval(t).f;
  out[1] = torque(t, q, qd);
}

}  // namespace refdyn
