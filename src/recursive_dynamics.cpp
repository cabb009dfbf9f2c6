#include "refdyn/recursive_dynamics.hpp"

#include "refdyn/error.hpp"
#include "refdyn/kinematics.hpp"

namespace refdyn {
namespace unchecked {

void rnea(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd* qd,
          const Eigen::VectorXd* qdd, bool gravity, Eigen::VectorXd& out) {
  const int n = model.nq;
  // Gravity enters as a fictitious base acceleration a_0 = −g (Featherstone §5.3).
  const Motion a0{Vec3::Zero(), gravity ? Vec3(-model.gravity) : Vec3::Zero()};
  for (int i = 0; i < n; ++i) {
    const SE3& X = data.liMi[i] = joint_placement(model, i, q[i]);
    const int p = model.parent[i];
    const Motion S = model.motion_subspace(i);
    Motion& v = data.v[i];
    Motion& a = data.a[i];
    if (qd) {
      const Motion vj = S * (*qd)[i];
      v = (p < 0 ? Motion::Zero() : X.act_inv(data.v[p])) + vj;
      a = X.act_inv(p < 0 ? a0 : data.a[p]) + v.cross(vj);
    } else {
      v = Motion::Zero();
      a = X.act_inv(p < 0 ? a0 : data.a[p]);
    }
    if (qdd) a += S * (*qdd)[i];
    const Inertia& I = model.inertia[i];
    data.f[i] = I * a;
    if (qd) data.f[i] += cross_force(v, I * v);
  }
  for (int i = n - 1; i >= 0; --i) {
    out[i] = dot(model.motion_subspace(i), data.f[i]);
    const int p = model.parent[i];
    if (p >= 0) data.f[p] += data.liMi[i].act(data.f[i]);
  }
}

void crba(const Model& model, Data& data, const Eigen::VectorXd& q) {
  const int n = model.nq;
  for (int i = 0; i < n; ++i) {
    data.liMi[i] = joint_placement(model, i, q[i]);
    data.Ic[i] = model.inertia[i];
  }
  for (int i = n - 1; i >= 0; --i) {
    const Motion S = model.motion_subspace(i);
    Force F = data.Ic[i] * S;
    data.M(i, i) = dot(S, F);
    int j = i;
    while (model.parent[j] >= 0) {
      F = data.liMi[j].act(F);
      j = model.parent[j];
      const double mij = dot(model.motion_subspace(j), F);
      data.M(i, j) = mij;
      data.M(j, i) = mij;
    }
    const int p = model.parent[i];
    if (p >= 0) data.Ic[p] += data.Ic[i].transformed(data.liMi[i]);
  }
}

}  // namespace unchecked

const Eigen::VectorXd& inverse_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  check_vector("qdd", qdd, model.nv);
  unchecked::rnea(model, data, q, &qd, &qdd, true, data.tau);
  return data.tau;
}

const Eigen::VectorXd& bias_forces(const Model& model, Data& data, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qd) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  unchecked::rnea(model, data, q, &qd, nullptr, true, data.nle);
  return data.nle;
}

const Eigen::VectorXd& gravity_forces(const Model& model, Data& data, const Eigen::VectorXd& q) {
  model.check_q(q);
  unchecked::rnea(model, data, q, nullptr, nullptr, true, data.g);
  return data.g;
}

const Eigen::MatrixXd& mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q) {
  model.check_q(q);
  unchecked::crba(model, data, q);
  return data.M;
}

const Eigen::VectorXd& forward_dynamics(const Model& model, Data& data, const Eigen::VectorXd& q,
                                        const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  check_vector("tau", tau, model.nv);
  unchecked::crba(model, data, q);
  unchecked::rnea(model, data, q, &qd, nullptr, true, data.nle);
  data.llt.compute(data.M);
  if (data.llt.info() != Eigen::Success)
    throw Error("forward_dynamics: the mass matrix is not positive definite at this q "
                "(hint: a massless link at the end of a chain, or a joint that moves no mass)");
  data.ddq = tau - data.nle;
  data.llt.solveInPlace(data.ddq);
  return data.ddq;
}

double kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  double T = 0;
  for (int i = 0; i < model.nq; ++i) {
    const SE3& X = data.liMi[i] = joint_placement(model, i, q[i]);
    const int p = model.parent[i];
    data.v[i] = (p < 0 ? Motion::Zero() : X.act_inv(data.v[p])) + model.motion_subspace(i) * qd[i];
    T += 0.5 * dot(data.v[i], model.inertia[i] * data.v[i]);
  }
  return T;
}

double potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q) {
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
