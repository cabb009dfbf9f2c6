// RNEA: inverse dynamics, bias forces, gravity (the fast double kernel; see kernels.hpp).
#include "refdyn/multibody/recursive_dynamics.hpp"

#include "kernels.hpp"

namespace refdyn {
namespace kernels {
namespace {

void rnea_dispatch(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
                   const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out, bool have_X) {
  const double* pq = q.data();
  const double* pqd = qd ? qd->data() : nullptr;
  const double* pqdd = qdd ? qdd->data() : nullptr;
  double* o = out.data();
  if (qd && qdd) rnea_impl<true, true>(model, data, pq, pqd, pqdd, gravity, o, have_X);
  else if (qd) rnea_impl<true, false>(model, data, pq, pqd, nullptr, gravity, o, have_X);
  else if (qdd) rnea_impl<false, true>(model, data, pq, nullptr, pqdd, gravity, o, have_X);
  else rnea_impl<false, false>(model, data, pq, nullptr, nullptr, gravity, o, have_X);
}

}  // namespace
}  // namespace kernels

using kernels::check_q_fast;
using kernels::check_vector_fast;
using kernels::rnea_dispatch;
using kernels::rnea_impl;

namespace unchecked {

void rnea(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
          const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out) {
  rnea_dispatch(model, data, q, qd, qdd, gravity, out, false);
}

void rnea_reusing_placements(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
                             const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out) {
  rnea_dispatch(model, data, q, qd, qdd, gravity, out, true);
}

}  // namespace unchecked

const Eigen::VectorXd& inverse_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  check_vector_fast("qdd", qdd, model.nv);
  rnea_impl<true, true>(model, data, q.data(), qd.data(), qdd.data(), true, data.tau.data(), false);
  return data.tau;
}

const Eigen::VectorXd& bias_forces(const Model& model, Data& data, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qd) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), false);
  return data.nle;
}

const Eigen::VectorXd& gravity_forces(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  check_q_fast(model, q);
  rnea_impl<false, false>(model, data, q.data(), nullptr, nullptr, true, data.g.data(), false);
  return data.g;
}

}  // namespace refdyn
