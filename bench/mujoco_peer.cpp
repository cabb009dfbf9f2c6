// MuJoCo as a dynamics peer: the MJCF writer and the calls (see mujoco_peer.hpp).
#include "mujoco_peer.hpp"

#include <mujoco/mujoco.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace refdyn_bench {
namespace {

void write_vec(std::ostringstream& s, const refdyn::Vec3& v) { s << v.x() << ' ' << v.y() << ' ' << v.z(); }

/// Body i and its subtree, depth first (MuJoCo's dof order).
void write_body(std::ostringstream& s, const refdyn::Model& model, const std::vector<std::vector<int>>& children,
                int i, int depth) {
  const std::string pad(2 * depth + 4, ' ');
  const refdyn::SE3& P = model.placement[i];
  const Eigen::Quaterniond quat(P.R);
  s << pad << "<body name=\"b" << i << "\" pos=\"";
  write_vec(s, P.p);
  s << "\" quat=\"" << quat.w() << ' ' << quat.x() << ' ' << quat.y() << ' ' << quat.z() << "\">\n";
  // refdyn's inertia is about the body origin (m, h = m c, I_O); MJCF takes the centre of mass
  // and the inertia about it, I_C = I_O − m (|c|² 1 − c cᵀ), here in principal axes (Eigen's
  // iterative symmetric eigensolver, accurate to rounding). Given a full inertia, MuJoCo's
  // compiler diagonalises it itself, to about 1e-7 relative only: the dynamics would then differ
  // from refdyn's by that much (measured; inertia_error() checks what MuJoCo holds).
  const refdyn::Inertia& I = model.inertia[i];
  const refdyn::Vec3 c = I.m > 0 ? refdyn::Vec3(I.h / I.m) : refdyn::Vec3::Zero();
  const refdyn::Mat3 Ic = I.I - I.m * (c.squaredNorm() * refdyn::Mat3::Identity() - c * c.transpose());
  const Eigen::SelfAdjointEigenSolver<refdyn::Mat3> es(Ic);
  refdyn::Mat3 V = es.eigenvectors();
  if (V.determinant() < 0) V.col(2) = -V.col(2);  // a rotation
  const Eigen::Quaterniond iq(V);
  const refdyn::Vec3 J = es.eigenvalues();
  s << pad << "  <inertial pos=\"";
  write_vec(s, c);
  s << "\" quat=\"" << iq.w() << ' ' << iq.x() << ' ' << iq.y() << ' ' << iq.z() << "\" mass=\"" << I.m
    << "\" diaginertia=\"";
  write_vec(s, J);
  s << "\"/>\n";
  s << pad << "  <joint name=\"j" << i << "\" type=\""
    << (model.joint_type[i] == refdyn::JointType::Prismatic ? "slide" : "hinge") << "\" axis=\"";
  write_vec(s, model.axis[i]);
  s << "\" armature=\"" << model.armature[i] << "\"/>\n";
  for (int child : children[i]) write_body(s, model, children, child, depth + 1);
  s << pad << "</body>\n";
}

}  // namespace

std::string MujocoPeer::mjcf(const refdyn::Model& model) {
  std::vector<std::vector<int>> children(model.nq);
  std::vector<int> roots;
  for (int i = 0; i < model.nq; ++i) (model.parent[i] < 0 ? roots : children[model.parent[i]]).push_back(i);
  std::ostringstream s;
  s.precision(17);
  s << "<mujoco model=\"refdyn\">\n"
    << "  <compiler angle=\"radian\" inertiafromgeom=\"false\"/>\n"
    << "  <option gravity=\"";
  write_vec(s, model.gravity);
  s << "\">\n    <flag contact=\"disable\" constraint=\"disable\"/>\n  </option>\n  <worldbody>\n";
  for (int r : roots) write_body(s, model, children, r, 0);
  s << "  </worldbody>\n</mujoco>\n";
  return s.str();
}

MujocoPeer::MujocoPeer(const refdyn::Model& model) : n_(model.nq), offset_(model.offset) {
  const std::string xml = mjcf(model);
  auto vfs = std::make_unique<mjVFS>();  // about 2 MB: not on the stack
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), "refdyn.xml", static_cast<int>(xml.size())) != 0)
    throw std::runtime_error("MuJoCo peer: cannot create the in-memory MJCF file");
  std::memcpy(vfs->filedata[vfs->nfile - 1], xml.data(), xml.size());
  char error[1000] = "";
  m_ = mj_loadXML("refdyn.xml", vfs.get(), error, sizeof error);
  mj_deleteVFS(vfs.get());
  if (!m_) throw std::runtime_error(std::string("MuJoCo rejected the model '") + model.name + "': " + error);
  if (m_->nv != n_) {
    const int nv = m_->nv;
    mj_deleteModel(m_);  // a throwing constructor runs no destructor
    throw std::runtime_error("MuJoCo peer: MuJoCo has " + std::to_string(nv) + " dofs, refdyn " + std::to_string(n_));
  }
  d_ = mj_makeData(m_);
  dof_.resize(n_);
  armature_.assign(n_, 0.0);
  for (int i = 0; i < n_; ++i) {
    const int j = mj_name2id(m_, mjOBJ_JOINT, ("j" + std::to_string(i)).c_str());
    dof_[i] = m_->jnt_dofadr[j];
    armature_[dof_[i]] = m_->dof_armature[dof_[i]];
    // MuJoCo's inertia of body i, about the body origin: R diag(J) Rᵀ + m (|c|² 1 − c cᵀ).
    const int b = mj_name2id(m_, mjOBJ_BODY, ("b" + std::to_string(i)).c_str());
    const double mass = m_->body_mass[b];
    const refdyn::Vec3 c(m_->body_ipos + 3 * b);
    const double* iq = m_->body_iquat + 4 * b;
    const refdyn::Mat3 R = Eigen::Quaterniond(iq[0], iq[1], iq[2], iq[3]).normalized().toRotationMatrix();
    const refdyn::Mat3 IO = R * refdyn::Vec3(m_->body_inertia + 3 * b).asDiagonal() * R.transpose() +
                            mass * (c.squaredNorm() * refdyn::Mat3::Identity() - c * c.transpose());
    const refdyn::Inertia& I = model.inertia[i];
    const double scale = std::max(I.I.cwiseAbs().maxCoeff(), 1e-300);
    inertia_error_ = std::max({inertia_error_, std::abs(mass - I.m) / std::max(I.m, 1e-300),
                               (IO - I.I).cwiseAbs().maxCoeff() / scale,
                               (mass * c - I.h).cwiseAbs().maxCoeff() / std::max(I.h.cwiseAbs().maxCoeff(), 1e-300)});
  }
  Mfull_.resize(static_cast<size_t>(n_) * n_);
  tmp_.resize(n_);
  out_.resize(n_);
  M_.resize(n_, n_);
  v_.resize(n_);
}

MujocoPeer::~MujocoPeer() {
  if (d_) mj_deleteData(d_);
  if (m_) mj_deleteModel(m_);
}

void MujocoPeer::to_mj(const Eigen::VectorXd& x, double* out, bool add_offset) const {
  for (int i = 0; i < n_; ++i) out[dof_[i]] = x[i] + (add_offset ? offset_[i] : 0.0);
}

void MujocoPeer::from_mj(const double* x, Eigen::VectorXd& out) const {
  for (int i = 0; i < n_; ++i) out[i] = x[dof_[i]];
}

void MujocoPeer::to_mj_state(const Eigen::VectorXd& q, const Eigen::VectorXd* qd, const Eigen::VectorXd* qdd) {
  to_mj(q, d_->qpos, true);
  if (qd) to_mj(*qd, d_->qvel, false);
  if (qdd) to_mj(*qdd, d_->qacc, false);
}

void MujocoPeer::set_state(const double* q_mj, const double* qd_mj) {
  std::copy(q_mj, q_mj + n_, d_->qpos);
  if (qd_mj) std::copy(qd_mj, qd_mj + n_, d_->qvel);
}

// ---- the pipelines ----

void MujocoPeer::run_mass_matrix() {
  mj_kinematics(m_, d_);
  mj_comPos(m_, d_);
  mj_crb(m_, d_);
  mj_fullM(m_, Mfull_.data(), d_->qM);
}

void MujocoPeer::run_bias_forces() {
  mj_kinematics(m_, d_);
  mj_comPos(m_, d_);
  mj_comVel(m_, d_);
  mj_rne(m_, d_, 0, d_->qfrc_bias);
}

void MujocoPeer::run_inverse_dynamics() {
  mj_kinematics(m_, d_);
  mj_comPos(m_, d_);
  mj_comVel(m_, d_);
  mj_rne(m_, d_, 1, out_.data());
  for (int i = 0; i < n_; ++i) out_[i] += armature_[i] * d_->qacc[i];
}

void MujocoPeer::run_forward_dynamics(const double* tau_mj) {
  mj_kinematics(m_, d_);
  mj_comPos(m_, d_);
  mj_crb(m_, d_);
  mj_factorM(m_, d_);
  mj_comVel(m_, d_);
  mj_rne(m_, d_, 0, d_->qfrc_bias);
  for (int i = 0; i < n_; ++i) tmp_[i] = tau_mj[i] - d_->qfrc_bias[i];
  mj_solveM(m_, d_, d_->qacc, tmp_.data(), 1);
}

// ---- one call each ----

const Eigen::MatrixXd& MujocoPeer::last_mass_matrix() {
  for (int i = 0; i < n_; ++i)
    for (int j = 0; j < n_; ++j) M_(i, j) = Mfull_[static_cast<size_t>(dof_[i]) * n_ + dof_[j]];
  return M_;
}

const Eigen::VectorXd& MujocoPeer::last_bias_forces() {
  from_mj(d_->qfrc_bias, v_);
  return v_;
}

const Eigen::VectorXd& MujocoPeer::last_tau() {
  from_mj(out_.data(), v_);
  return v_;
}

const Eigen::VectorXd& MujocoPeer::last_qdd() {
  from_mj(d_->qacc, v_);
  return v_;
}

const Eigen::MatrixXd& MujocoPeer::mass_matrix(const Eigen::VectorXd& q) {
  to_mj_state(q, nullptr, nullptr);
  run_mass_matrix();
  return last_mass_matrix();
}

const Eigen::VectorXd& MujocoPeer::bias_forces(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  to_mj_state(q, &qd, nullptr);
  run_bias_forces();
  return last_bias_forces();
}

const Eigen::VectorXd& MujocoPeer::inverse_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                    const Eigen::VectorXd& qdd) {
  to_mj_state(q, &qd, &qdd);
  run_inverse_dynamics();
  return last_tau();
}

const Eigen::VectorXd& MujocoPeer::inverse_dynamics_pipeline(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                             const Eigen::VectorXd& qdd) {
  to_mj_state(q, &qd, &qdd);
  mj_inverse(m_, d_);
  from_mj(d_->qfrc_inverse, v_);
  return v_;
}

const Eigen::VectorXd& MujocoPeer::forward_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                    const Eigen::VectorXd& tau) {
  to_mj_state(q, &qd, nullptr);
  std::vector<double> t(n_);
  to_mj(tau, t.data(), false);
  run_forward_dynamics(t.data());
  return last_qdd();
}

// ---- timed kernels ----

void MujocoPeer::load_states(const std::vector<Eigen::VectorXd>& q, const std::vector<Eigen::VectorXd>& qd,
                             const std::vector<Eigen::VectorXd>& qdd, const std::vector<Eigen::VectorXd>& tau) {
  const size_t count = q.size();
  for (auto* v : {&sq_, &sqd_, &sqdd_, &stau_}) v->assign(count * n_, 0.0);
  for (size_t k = 0; k < count; ++k) {
    to_mj(q[k], sq_.data() + k * n_, true);
    to_mj(qd[k], sqd_.data() + k * n_, false);
    to_mj(qdd[k], sqdd_.data() + k * n_, false);
    to_mj(tau[k], stau_.data() + k * n_, false);
  }
}

void MujocoPeer::time_mass_matrix(int k) {
  set_state(stored(sq_, k), nullptr);
  run_mass_matrix();
}

void MujocoPeer::time_bias_forces(int k) {
  set_state(stored(sq_, k), stored(sqd_, k));
  run_bias_forces();
}

void MujocoPeer::time_inverse_dynamics(int k) {
  set_state(stored(sq_, k), stored(sqd_, k));
  const double* a = stored(sqdd_, k);
  std::copy(a, a + n_, d_->qacc);
  run_inverse_dynamics();
}

void MujocoPeer::time_forward_dynamics(int k) {
  set_state(stored(sq_, k), stored(sqd_, k));
  run_forward_dynamics(stored(stau_, k));
}

}  // namespace refdyn_bench
