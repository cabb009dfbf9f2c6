// The entry points of recursive_dynamics.hpp that are not one algorithm: forward_dynamics' choice
// between ABA and CRBA + Cholesky, and the energies. The fast double kernels are in rnea.cpp,
// crba.cpp and aba.cpp, their shared steps in kernels.hpp (speed notes there).
#include "refdyn/multibody/recursive_dynamics.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/common/text.hpp"

#include "kernels.hpp"

namespace refdyn {

namespace kernels {
void check_forward_dynamics_arguments(const Model& model, const Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  check_data(model, data);
  check_q_fast(model, q);
  check_vector_fast("qd", qd, model.nv);
  check_vector_fast("tau", tau, model.nv);
}
}  // namespace kernels

const Eigen::VectorXd& forward_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  return forward_dynamics_uses_aba(model.nq) ? forward_dynamics_aba(model, data, q, qd, tau)
                                             : forward_dynamics_crba(model, data, q, qd, tau);
}

double kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  check_data(model, data);
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  double T = 0;
  for (int i = 0; i < model.nq; ++i) {
    const SE3& X = data.liMi[i] = joint_placement(model, i, q[i]);
    const int p = model.parent[i];
    data.v[i] = (p < 0 ? Motion::Zero() : X.act_inv(data.v[p])) + model.motion_subspace(i) * qd[i];
    T += 0.5 * dot(data.v[i], model.inertia[i] * data.v[i]);
    if (model.armature[i] != 0) T += 0.5 * model.armature[i] * qd[i] * qd[i];
  }
  return T;
}

double potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  forward_kinematics(model, data, q);
  double V = 0;
  for (int i = 0; i < model.nq; ++i) {
    const Inertia& I = model.inertia[i];
    const Vec3 mc_world = data.oMi[i].R * I.h + I.m * data.oMi[i].p;
    V -= model.gravity.dot(mc_world);
  }
  return V;
}

}  // namespace refdyn
