#include "refdyn/trace_dynamics.hpp"

#include "refdyn/error.hpp"
#include "refdyn/kinematics.hpp"

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
  check_index(model, l, "trace_dT body index l");
  check_index(model, i, "trace_dT joint index i");
  if (!in_support(model, l, i)) return Mat4::Zero();
  return data.D[i] * data.T[l];
}

Mat4 trace_ddT(const Model& model, const Data& data, int l, int i, int j) {
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
  for (int l = 0; l < n; ++l) {
    const auto& sup = model.support[l];
    for (int i : sup) {
      const Mat4 TiH = trace_dT(model, data, l, i) * data.H[l];
      for (int j : sup) {
        if (j > i) continue;
        const Mat4 Tj = trace_dT(model, data, l, j);
        const double m = (TiH.cwiseProduct(Tj)).sum();  // tr(A Bᵀ) = Σ A∘B
        data.M_trace(i, j) += m;
        if (i != j) data.M_trace(j, i) += m;
      }
    }
  }
  return data.M_trace;
}

const Eigen::VectorXd& trace_coriolis(const Model& model, Data& data, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& qd) {
  check_vector("qd", qd, model.nv);
  trace_kinematics(model, data, q);
  const int n = model.nq;
  data.c_trace.setZero();
  for (int l = 0; l < n; ++l) {
    const auto& sup = model.support[l];
    Mat4 A = Mat4::Zero(), Td = Mat4::Zero();
    for (int j : sup) {
      Td += trace_dT(model, data, l, j) * qd[j];
      for (int k : sup) A += trace_ddT(model, data, l, j, k) * (qd[j] * qd[k]);
    }
    data.Tdd[l] = A;
    data.Td[l] = Td;
    const Mat4 HA = data.H[l] * A.transpose();
    for (int i : sup) data.c_trace[i] += (trace_dT(model, data, l, i) * HA).trace();
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
    for (int i : model.support[l]) data.g_trace[i] -= gt.dot(trace_dT(model, data, l, i) * He4);
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
    for (int i : model.support[l]) Td += trace_dT(model, data, l, i) * qd[i];
    T += 0.5 * (Td * data.H[l] * Td.transpose()).trace();
  }
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
