// ReferencePlanner and JerkPlanner (planner.hpp): the two reference dynamics behind one
// interface, delegating to plan_motion and plan_jerk_motion.
#include "refdyn/simulate/planner.hpp"

#include "refdyn/simulate/plan.hpp"
#include "refdyn/common/error.hpp"

#include <sstream>

namespace refdyn {

void Planner::jacobian(double, const Eigen::VectorXd&, Eigen::MatrixXd&) {
  const std::string d = description();
  throw Error("this planner" + (d.empty() ? std::string() : " (" + d + ")") + " has no exact Jacobian, which method: "
              "bdf needs (hint: integrator method rk4 or dopri5; problems with jerk constraints are not integrated "
              "implicitly yet)");
}

ReferencePlanner::ReferencePlanner(std::unique_ptr<ReferenceDynamics> rd) : owned_(std::move(rd)), rd_(owned_.get()) {}
ReferencePlanner::ReferencePlanner(ReferenceDynamics& rd) : rd_(&rd) {}

Eigen::VectorXd ReferencePlanner::initial_state(double, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                                const Eigen::VectorXd*) {
  return rd_->make_state(q0, qd0);
}

Plan ReferencePlanner::plan(const Eigen::VectorXd& x0, const PlanSettings& s) {
  return plan_motion(*rd_, x0, s);
}

std::vector<RowResidual> ReferencePlanner::row_residuals() const {
  const ConstraintEval& ev = rd_->constraints();
  return {{"|Phi|", ev.phi.cwiseAbs()}, {"|dPhi/dt|", ev.phid.cwiseAbs()}};
}

std::optional<PlannerPartition> ReferencePlanner::partition() const {
  return PlannerPartition{rd_->independent(), rd_->dependent(), rd_->partition_condition()};
}

JerkPlanner::JerkPlanner(std::unique_ptr<JerkDynamics> jd) : owned_(std::move(jd)), jd_(owned_.get()) {}
JerkPlanner::JerkPlanner(JerkDynamics& jd) : jd_(&jd) {}

std::vector<std::string> JerkPlanner::state_names() const {
  std::vector<std::string> names;
  for (const std::string& j : jd_->model().joint_name) names.push_back("acc_" + j);
  if (jd_->forces())
    for (const std::string& z : jd_->forces()->state_names()) names.push_back(z);
  return names;
}

Plan JerkPlanner::plan(const Eigen::VectorXd& x0, const PlanSettings& s) {
  return plan_jerk_motion(*jd_, x0, s);
}

std::vector<RowResidual> JerkPlanner::row_residuals() const {
  if (static_cast<int>(jd_->constraints().size()) == jd_->num_constraints())  // jerk rows only
    return {{"|B qddd + s|", jd_->row_residual().cwiseAbs()}};
  return {{"|Phi| (jerk rows: |B qddd + s|)", jd_->row_residual().cwiseAbs()},
          {"|dPhi/dt|", jd_->row_rate_residual().cwiseAbs()}};
}

std::string JerkPlanner::description() const {
  std::ostringstream o;
  o << "jerk-level problem (p = 3): state [q; qd; qdd" << (jd_->num_states() ? "; z" : "") << "], kappa = "
    << jd_->options().kappa << " 1/s";
  if (static_cast<int>(jd_->constraints().size()) < jd_->num_constraints())
    o << "; rows of order <= 2 taken to the jerk level (d/dt psi + kappa psi = 0, psi their Baumgarte-stabilized "
         "acceleration level)";
  o << "; no partition: a KKT system with the mass matrix (partition: is not used)";
  return o.str();
}

}  // namespace refdyn
