#pragma once
// TEMPORARY (lead's branch only, replaced by helper A's constraints.hpp API at merge).
#include "refdyn/constraints/constraints.hpp"
#include "refdyn/multibody/dual.hpp"
namespace refdyn {
struct ConstraintEvalDual {
  ConstraintEvalDual(const Model& model, const ConstraintSet& set)
      : phi(set.rows()), phid(set.rows()), gamma(set.rows()), A(static_cast<size_t>(set.rows()) * model.nq) {}
  std::vector<JacobianScalar> phi, phid, gamma, A;
};
inline void evaluate_constraints_dual(const Model&, const ConstraintSet& set, ConstraintEvalDual&, double,
                                      const JacobianScalar*, const JacobianScalar*) {
  if (set.rows() > 0) throw Error("stub: constraints have no dual evaluation yet");
}
}  // namespace refdyn
