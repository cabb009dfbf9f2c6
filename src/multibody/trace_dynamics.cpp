#include "refdyn/multibody/trace_dynamics.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"

#include <algorithm>

namespace refdyn {

namespace {
bool in_support(const Model& model, int l, int i) {
  // i is an ancestor of l (or l): walk up from l; bodies are ordered parents-first.
  for (int k = l; k >= 0 && k >= i; k = model.parent[k])
    if (k == i) return true;
  return false;
}
}  // namespace

void trace_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q) {
  forward_kinematics(model, data, q);
  for (int i = 0; i < model.nq; ++i) {
    const SE3& X = data.oMi[i];
    data.T[i] = X.matrix();
    const Vec3 u = X.R * model.axis[i];
    Mat4& D = data.D[i];
    D.setZero();
    if (model.joint_type[i] == JointType::Revolute) {
      D.topLeftCorner<3, 3>() = skew(u);
      D.topRightCorner<3, 1>() = X.p.cross(u);
    } else {
      D.topRightCorner<3, 1>() = u;
    }
  }
}

namespace {
void check_index(const Model& model, int k, const char* what) {
  if (k < 0 || k >= model.nq)
    throw Error(expected_got(what, "an index in 0 .. " + std::to_string(model.nq - 1), std::to_string(k),
                             "bodies and joints are numbered in model order"));
}
}  // namespace

Mat4 trace_dT(const Model& model, const Data& data, int l, int i) {
  check_data(model, data);
  check_index(model, l, "trace_dT body index l");
  check_index(model, i, "trace_dT joint index i");
  if (!in_support(model, l, i)) return Mat4::Zero();
  return data.D[i] * data.T[l];
}

Mat4 trace_ddT(const Model& model, const Data& data, int l, int i, int j) {
  check_data(model, data);
  check_index(model, l, "trace_ddT body index l");
  check_index(model, i, "trace_ddT joint index i");
  check_index(model, j, "trace_ddT joint index j");
  if (!in_support(model, l, i) || !in_support(model, l, j)) return Mat4::Zero();
  // Both are ancestors of l, so one is an ancestor of the other; the ancestor's D goes left.
  const int a = std::min(i, j), b = std::max(i, j);
  return data.D[a] * data.D[b] * data.T[l];
}

const Eigen::MatrixXd& trace_mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q) {
  trace_kinematics(model, data, q);
  const int n = model.nq;
  data.M_trace.setZero();
  // Per body l: T_i^(l) = D_i T^(l) for every i in its support (each computed once), then
  // m_ij^(l) = tr(T_i H T_jᵀ) = Σ (T_i H) ∘ T_j. O(n³) 4×4 work in total.
  std::vector<Mat4> Ti;
  for (int l = 0; l < n; ++l) {
    const auto& sup = model.support[l];
    Ti.resize(sup.size());
    for (size_t a = 0; a < sup.size(); ++a) Ti[a] = data.D[sup[a]] * data.T[l];
    for (size_t a = 0; a < sup.size(); ++a) {
      const Mat4 TiH = Ti[a] * data.H[l];
      for (size_t b = 0; b <= a; ++b) {
        const double m = TiH.cwiseProduct(Ti[b]).sum();
        data.M_trace(sup[a], sup[b]) += m;
        if (a != b) data.M_trace(sup[b], sup[a]) += m;
      }
    }
  }
  for (int i = 0; i < n; ++i)
    if (model.armature[i] != 0) data.M_trace(i, i) += model.armature[i];  // the joints' armature
  return data.M_trace;
}

const Eigen::VectorXd& trace_coriolis(const Model& model, Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd) {
  check_vector("qd", qd, model.nv);
  trace_kinematics(model, data, q);
  const int n = model.nq;
  data.c_trace.setZero();
  for (int l = 0; l < n; ++l) {
    const auto& sup = model.support[l];  // ancestors first, so sup[a] is an ancestor of sup[b] for a < b
    Mat4 A = Mat4::Zero(), Td = Mat4::Zero();
    // Σ_jk T_jk q̇_j q̇_k with T_jk = D_a D_b T (a the ancestor): diagonal terms once, the
    // off-diagonal ones twice.
    for (size_t a = 0; a < sup.size(); ++a) {
      const Mat4 DaT = data.D[sup[a]] * data.T[l];
      Td += DaT * qd[sup[a]];
      for (size_t b = a; b < sup.size(); ++b) {
        const double w = (a == b ? 1.0 : 2.0) * qd[sup[a]] * qd[sup[b]];
        A += (data.D[sup[a]] * (data.D[sup[b]] * data.T[l])) * w;
      }
    }
    data.Tdd[l] = A;
    data.Td[l] = Td;
    const Mat4 HA = data.H[l] * A.transpose();
    for (int i : sup) data.c_trace[i] += (data.D[i] * data.T[l] * HA).trace();
  }
  return data.c_trace;
}

const Eigen::VectorXd& trace_gravity(const Model& model, Data& data, const Eigen::VectorXd& q) {
  trace_kinematics(model, data, q);
  Eigen::Vector4d gt;
  gt << model.gravity, 0.0;
  data.g_trace.setZero();
  for (int l = 0; l < model.nq; ++l) {
    const Eigen::Vector4d He4 = data.H[l].col(3);
    for (int i : model.support[l]) data.g_trace[i] -= gt.dot(data.D[i] * (data.T[l] * He4));
  }
  return data.g_trace;
}

double trace_kinetic_energy(const Model& model, Data& data, const Eigen::VectorXd& q,
                            const Eigen::VectorXd& qd) {
  check_vector("qd", qd, model.nv);
  trace_kinematics(model, data, q);
  double T = 0;
  for (int l = 0; l < model.nq; ++l) {
    Mat4 Td = Mat4::Zero();
    for (int i : model.support[l]) Td += data.D[i] * data.T[l] * qd[i];
    T += 0.5 * (Td * data.H[l] * Td.transpose()).trace();
  }
  for (int i = 0; i < model.nq; ++i)
    if (model.armature[i] != 0) T += 0.5 * model.armature[i] * qd[i] * qd[i];
  return T;
}

double trace_potential_energy(const Model& model, Data& data, const Eigen::VectorXd& q) {
  trace_kinematics(model, data, q);
  Eigen::Vector4d gt;
  gt << model.gravity, 0.0;
  double V = 0;
  for (int l = 0; l < model.nq; ++l) V -= gt.dot(data.T[l] * data.H[l].col(3));
  return V;
}

TracePointKinematics trace_point_kinematics(const Model& model, Data& data, int point,
                                            const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  if (point < 0 || point >= static_cast<int>(model.point_name.size()))
    throw Error(expected_got("point index", "0 .. " + std::to_string(model.point_name.size()) + " - 1",
                             std::to_string(point)));
  check_vector("qd", qd, model.nv);
  trace_kinematics(model, data, q);
  TracePointKinematics out{Vec3::Zero(), Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nq),
                           Vec3::Zero()};
  const int l = model.point_body[point];
  Eigen::Vector4d r;
  r << model.point_position[point], 1.0;
  if (l < 0) {
    out.position = model.point_position[point];
    return out;
  }
  out.position = (data.T[l] * r).head<3>();
  Mat4 A = Mat4::Zero();
  for (int i : model.support[l]) {
    out.C.col(i) = (trace_dT(model, data, l, i) * r).head<3>();
    for (int j : model.support[l]) A += trace_ddT(model, data, l, i, j) * (qd[i] * qd[j]);
  }
  out.d = (A * r).head<3>();
  return out;
}

}  // namespace refdyn
