#include "refdyn/multibody/kinematics.hpp"

#include "refdyn/common/error.hpp"

#include <cmath>

namespace refdyn {

SE3 joint_placement(const Model& model, int i, double qi) {
  const SE3& P = model.placement[i];
  const Vec3& u = model.axis[i];
  const double x = qi + model.offset[i];
  SE3 X;
  if (model.joint_type[i] == JointType::Revolute) {
    const double c = std::cos(x), s = std::sin(x);
    if (u.x() == 0.0 && u.y() == 0.0) {  // axis ±z, the DH case
      const double ss = u.z() > 0 ? s : -s;
      X.R.col(0) = c * P.R.col(0) + ss * P.R.col(1);
      X.R.col(1) = -ss * P.R.col(0) + c * P.R.col(1);
      X.R.col(2) = P.R.col(2);
    } else {  // Rodrigues: R = c 1 + s [u]x + (1-c) u uᵀ
      Mat3 Rj = c * Mat3::Identity() + s * skew(u) + (1 - c) * u * u.transpose();
      X.R.noalias() = P.R * Rj;
    }
    X.p = P.p;
  } else {
    X.R = P.R;
    if (u.x() == 0.0 && u.y() == 0.0)  // axis ±z: a column instead of a product
      X.p = P.p + (u.z() * x) * P.R.col(2);
    else
      X.p = P.p + P.R * (u * x);
  }
  return X;
}

void unchecked::forward_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q) {
  for (int i = 0; i < model.nq; ++i) {
    const SE3 X = joint_placement(model, i, q[i]);
    data.liMi[i] = X;
    const int p = model.parent[i];
    SE3& O = data.oMi[i];
    if (p < 0) {
      O = X;
    } else {
      const SE3& Op = data.oMi[p];
      O.R.noalias() = Op.R * X.R;
      O.p.noalias() = Op.R * X.p;
      O.p += Op.p;
    }
  }
}

void forward_kinematics(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  model.check_q(q);
  unchecked::forward_kinematics(model, data, q);
}

namespace {
void check_point(const Model& model, int point) {
  if (point < 0 || point >= static_cast<int>(model.point_name.size()))
    throw Error(expected_got("point index", "0 .. " + std::to_string(model.point_name.size()) + " - 1",
                             std::to_string(point), "look the index up with Model::point_index(name)"));
}
}  // namespace

Vec3 point_position(const Model& model, const Data& data, int point) {
  check_data(model, data);
  check_point(model, point);
  const int b = model.point_body[point];
  return b < 0 ? model.point_position[point] : data.oMi[b].act_point(model.point_position[point]);
}

namespace kinematics_detail {

void propagate_velocity_drift(const Model& model, Data& data, int i, const Eigen::VectorXd& qd) {
  const int p = model.parent[i];
  const Motion vj = model.motion_subspace(i) * qd[i];
  if (p < 0) {
    data.v[i] = vj;
    data.a[i] = Motion::Zero();
  } else {
    data.v[i] = data.liMi[i].act_inv(data.v[p]) + vj;
    data.a[i] = data.liMi[i].act_inv(data.a[p]) + data.v[i].cross(vj);
  }
}

void point_jacobian_at(const Model& model, const Data& data, int b, const Vec3& r,
                       Eigen::Matrix<double, 3, Eigen::Dynamic>& C, Eigen::Matrix<double, 3, Eigen::Dynamic>& Jw) {
  C.setZero();
  Jw.setZero();
  if (b < 0) return;
  for (int i : model.support[b]) {
    const Vec3 u = data.oMi[i].R * model.axis[i];
    if (model.joint_type[i] == JointType::Revolute) {
      Jw.col(i) = u;
      C.col(i) = u.cross(r - data.oMi[i].p);
    } else {
      C.col(i) = u;
    }
  }
}

PointDrift point_drift_on_body(const Data& data, int b, const Vec3& r) {
  const Motion& v = data.v[b];
  const Motion& a = data.a[b];
  const Vec3 vel_b = v.v + v.w.cross(r);
  const Vec3 acc_b = a.v + a.w.cross(r) + v.w.cross(vel_b);
  const Mat3& R = data.oMi[b].R;
  return {R * vel_b, R * acc_b, R * v.w, R * a.w};
}

}  // namespace kinematics_detail

void point_jacobian(const Model& model, Data& data, int point) {
  check_data(model, data);
  check_point(model, point);
  const int b = model.point_body[point];
  const Vec3 r = b < 0 ? model.point_position[point] : data.oMi[b].act_point(model.point_position[point]);
  kinematics_detail::point_jacobian_at(model, data, b, r, data.Jp, data.Jw);
}

SE3 link_transform(const Model& model, const Data& data, int body) {
  check_data(model, data);
  if (body < 0 || body >= model.nq)
    throw Error(expected_got("body index", "0 .. nq-1", std::to_string(body)));
  return data.oMi[body] * model.link_offset[body];
}

PointDrift point_drift(const Model& model, Data& data, int point, const Eigen::VectorXd& qd) {
  check_data(model, data);
  check_point(model, point);
  check_vector("qd", qd, model.nv);
  PointDrift out{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  const int b = model.point_body[point];
  if (b < 0) return out;
  // Spatial velocity and drift acceleration along the support chain, in body frames.
  for (int i : model.support[b]) kinematics_detail::propagate_velocity_drift(model, data, i, qd);
  out = kinematics_detail::point_drift_on_body(data, b, model.point_position[point]);
  return out;
}

}  // namespace refdyn
