// ForceSet: the elements of a scenario side by side, their states concatenated; and the
// defaults of the ForceElement interface. Each element is one file (damping.cpp, spring.cpp,
// effort.cpp, flexible_drive.cpp, lugre.cpp), written once as a law (ForceLaw).
#include "refdyn/forces/force_elements.hpp"

#include "refdyn/common/error.hpp"

#include <algorithm>

namespace refdyn {

void ForceElement::apply_dual(double, const JacobianScalar*, const JacobianScalar*, const JacobianScalar*,
                              JacobianScalar*, JacobianScalar*) const {
  throw Error("force element '" + name() + "' has no exact derivatives (ForceElement::apply_dual), which implicit "
              "integration needs (hint: use method: rk4 or dopri5, or implement apply_dual for this element)");
}

void ForceSet::evaluate_dual(double t, const JacobianScalar* q, const JacobianScalar* qd, const JacobianScalar* z,
                             int nq, JacobianScalar* Q, JacobianScalar* zdot) const {
  for (int i = 0; i < nq; ++i) Q[i] = JacobianScalar(0.0);
  for (size_t k = 0; k < elements_.size(); ++k)
    elements_[k]->apply_dual(t, q, qd, z + offsets_[k], Q, zdot + offsets_[k]);
}

void ForceSet::add(ForceElementPtr e) {
  if (!e) throw Error("ForceSet::add: expected a force element, got none");
  offsets_.push_back(nz_);
  nz_ += e->num_states();
  elements_.push_back(std::move(e));
}

/// The states' column names, distinct: an element's own name (LuGre: z_<joint>) unless another
/// element of the set has a state of that name too (two LuGre elements on one joint); then each
/// of them is suffixed "_<label>" (its scenario `name:`) or, unnamed, "_<k>", its ordinal among
/// the elements sharing the name (z_j2_1, z_j2_2). A set without such duplicates (every scenario
/// before this rule) keeps its names.
std::vector<std::string> ForceSet::state_names() const {
  std::vector<std::string> raw;
  std::vector<const ForceElement*> owner;
  for (const auto& e : elements_)
    for (auto& s : e->state_names()) {
      raw.push_back(s);
      owner.push_back(e.get());
    }
  std::vector<std::string> n = raw;
  for (size_t i = 0; i < raw.size(); ++i) {
    int ordinal = 0, count = 0;
    for (size_t j = 0; j < raw.size(); ++j)
      if (raw[j] == raw[i]) {
        ++count;
        if (j <= i) ++ordinal;
      }
    if (count > 1) n[i] = raw[i] + "_" + (owner[i]->label.empty() ? std::to_string(ordinal) : owner[i]->label);
  }
  return n;
}

void ForceSet::evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                        Eigen::VectorXd& Q, double* zdot, Eigen::MatrixXd* dQ) const {
  Q.setZero();
  if (dQ) dQ->setZero();
  for (size_t k = 0; k < elements_.size(); ++k)
    elements_[k]->apply(t, q, qd, z + offsets_[k], Q, zdot + offsets_[k], dQ);
}

Eigen::VectorXd ForceSet::element_force(int k, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                        const double* z) const {
  Eigen::VectorXd Q;
  std::vector<double> zd;
  element_force(k, t, q, qd, z, Q, zd);
  return Q;
}

void ForceSet::element_force(int k, double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const double* z,
                             Eigen::VectorXd& Q, std::vector<double>& zdot) const {
  Q.setZero(q.size());
  zdot.resize(static_cast<size_t>(std::max(1, elements_[k]->num_states())));
  elements_[k]->apply(t, q, qd, z + offsets_[k], Q, zdot.data(), nullptr);
}

}  // namespace refdyn
