// CRBA (body frame and world frame), the fused M, c + g sweep, the mass-matrix Cholesky and
// forward dynamics by CRBA + Cholesky (the fast double kernels; see kernels.hpp).
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/common/crossovers.hpp"

#include "kernels.hpp"

namespace refdyn {
namespace kernels {
namespace {

/// Body-frame CRBA (Featherstone's): best for small models.
void crba_local(const Model& model, Data& data, const double* q) {
  const int n = model.nq;
  const bool chain = all_joint_transforms(model, data, q);
  if (!chain) start_tree_composites(model, data);
  InertiaCarry c;
  for (int i = n - 1; i >= 0; --i) {
    M3 R;
    v4 p;
    load_transform(data.liMi[i], R, p);
    crba_backward_body(model, data, i, chain, R, p, c, data.M.data(), data.M.rows());
  }
}

/// Body-frame CRBA and RNEA (q̈ = 0, gravity) in one forward and one backward sweep: each
/// joint transform is computed once and loaded once on the way back (small models).
void crba_bias_local(const Model& model, Data& data, const double* q, const double* qd, double* nle) {
  const int n = model.nq;
  const v4 a0 = -ld3(model.gravity);
  MotionCarry motion{splat(0.0), splat(0.0), splat(0.0), splat(0.0)};
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    M3 R;
    v4 p;
    if (i % kBlock == 0) joint_sincos(model, q, i, sn, cs);
    joint_transform(model, i, k, q[i], cs[i % kBlock], sn[i % kBlock], R, p, data.liMi[i]);
    chain &= model.parent[i] == i - 1;
    rnea_forward_body<true, false>(model, data, i, k, R, p, qd, nullptr, a0, motion);
  }
  if (!chain) start_tree_composites(model, data);
  ForceCarry force;
  InertiaCarry inertia;
  for (int i = n - 1; i >= 0; --i) {
    M3 R;
    v4 p;
    load_transform(data.liMi[i], R, p);
    rnea_backward_body(model, data, i, R, p, force, nle);
    crba_backward_body(model, data, i, chain, R, p, inertia, data.M.data(), data.M.rows());
  }
}

/// Bodies whose world axes fit the stack buffer of crba_world (6 doubles each).
constexpr int kWorldAxesOnStack = 128;

/// World-frame CRBA: composite inertias and joint axes in {0}, so M_ji = S_j·(Ic_i S_i) for
/// every ancestor j of i; best for larger models. For a serial chain the ancestors of i are
/// 0 .. i-1 and column i above the diagonal is one vectorised pass over the axes stored by
/// component. data.Ic ends holding the composites expressed in {0}, data.oMi the body poses.
/// Starts on a 64-byte boundary: its speed depended on where unrelated code placed it (chain60 M
/// 2.84–2.93 µs at 0 mod 64, 3.30–3.35 µs at 32 mod 64, the same machine code; bench/README.md).
REFDYN_ALIGNED_64 void crba_world(const Model& model, Data& data, const double* q) {
  const int n = model.nq;
  // Joint axes in {0}, by component (sw.x, sw.y, sw.z, sv.x, sv.y, sv.z).
  alignas(64) double S[6][kWorldAxesOnStack];
  const bool axes_on_stack = n <= kWorldAxesOnStack;
  bool chain = true;
  double sn[kBlock], cs[kBlock];
  M3 OR{};
  v4 Op{};
  for (int i = 0; i < n; ++i) {
    const JointKind k = joint_kind(model, i);
    chain &= world_pose_step(model, data, q, i, k, sn, cs, OR, Op);
    if (axes_on_stack) {
      v4 sw, sv;
      world_axis(model, i, k, OR, Op, sw, sv);
      for (int c = 0; c < 3; ++c) {
        S[c][i] = sw[c];
        S[3 + c][i] = sv[c];
      }
    }
  }
  if (!chain) {  // trees accumulate the composites of non-adjacent children in data.Ic, and
    for (int i = 0; i < n; ++i) data.Ic[i] = Inertia::Zero();
    data.M.setZero();  // M_ij of bodies on different branches is 0 (never written below)
  }
  double* M = data.M.data();
  const Eigen::Index ld_M = data.M.rows();
  bool carry = false;
  In c{};
  for (int i = n - 1; i >= 0; --i) {
    M3 OR_i;
    v4 Op_i;
    load_transform(data.oMi[i], OR_i, Op_i);
    In Ic = transform(ld(model.inertia[i]), OR_i, Op_i);
    if (!chain) add(Ic, ld(data.Ic[i]));
    if (carry) add(Ic, c);
    st(Ic, data.Ic[i]);
    const JointKind k = joint_kind(model, i);
    v4 sw, sv;
    world_axis(model, i, k, OR_i, Op_i, sw, sv);
    // F = Ic S = (I sw + h × sv, m sv − h × sw).
    const v4 Fn = mul(Ic.I, sw) + cross(Ic.h, sv);
    const v4 Ff = splat(Ic.m) * sv + cross(sw, Ic.h);
    double* Mi = M + ld_M * i;  // column i
    Mi[i] = dot3(sw, Fn) + dot3(sv, Ff);
    if (chain && axes_on_stack) {
      const double f0 = Fn[0], f1 = Fn[1], f2 = Fn[2], f3 = Ff[0], f4 = Ff[1], f5 = Ff[2];
      for (int j = 0; j < i; ++j)
        Mi[j] = S[0][j] * f0 + S[1][j] * f1 + S[2][j] * f2 + S[3][j] * f3 + S[4][j] * f4 + S[5][j] * f5;
    } else {
      for (int j = model.parent[i]; j >= 0; j = model.parent[j]) {
        v4 swj, svj;
        if (axes_on_stack) {
          swj = v4{S[0][j], S[1][j], S[2][j], 0.0};
          svj = v4{S[3][j], S[4][j], S[5][j], 0.0};
        } else {
          M3 ORj;
          v4 Opj;
          load_transform(data.oMi[j], ORj, Opj);
          world_axis(model, j, joint_kind(model, j), ORj, Opj, swj, svj);
        }
        Mi[j] = dot3(swj, Fn) + dot3(svj, Ff);
      }
    }
    const int par = model.parent[i];
    carry = false;
    if (par == i - 1) {
      c = Ic;
      carry = true;
    } else if (par >= 0) {
      In Ip = ld(data.Ic[par]);
      add(Ip, Ic);
      st(Ip, data.Ic[par]);
    }
  }
  // Lower triangle from the upper one (rows of a column-major matrix are strided).
  for (int i = 0; i < n; ++i) {
    const double* Mi = M + ld_M * i;
    if (chain) {
      for (int j = 0; j < i; ++j) M[i + ld_M * j] = Mi[j];
    } else {
      for (int j = model.parent[i]; j >= 0; j = model.parent[j]) M[i + ld_M * j] = Mi[j];
    }
  }
}

void crba_impl(const Model& model, Data& data, const Eigen::VectorXd& q) {
  if (model.nq < kWorldCrbaFrom) crba_local(model, data, q.data());
  else crba_world(model, data, q.data());
  add_armature(model, data.M.data(), data.M.rows());
}

}  // namespace
}  // namespace kernels

using kernels::check_forward_dynamics_arguments;
using kernels::check_q_fast;
using kernels::crba_bias_local;
using kernels::crba_impl;
using kernels::crba_world;
using kernels::rnea_impl;

namespace unchecked {

void crba(const Model& model, Data& data, const Eigen::VectorXd& q) { crba_impl(model, data, q); }

namespace {
template <int N>
bool solve_fixed(const Eigen::MatrixXd& M, Eigen::VectorXd& b) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(Eigen::Map<const Eigen::Matrix<double, N, N>>(M.data()));
  if (llt.info() != Eigen::Success) return false;
  Eigen::Map<Eigen::Matrix<double, N, 1>> x(b.data());
  llt.solveInPlace(x);
  return true;
}
}  // namespace

bool solve_mass_matrix(Data& data, Eigen::VectorXd& b) {
  switch (data.M.rows()) {  // fixed-size Cholesky on the stack for small models
    case 1: return solve_fixed<1>(data.M, b);
    case 2: return solve_fixed<2>(data.M, b);
    case 3: return solve_fixed<3>(data.M, b);
    case 4: return solve_fixed<4>(data.M, b);
    default:
      data.llt.compute(data.M);
      if (data.llt.info() != Eigen::Success) return false;
      data.llt.solveInPlace(b);
      return true;
  }
}

void mass_matrix_and_bias(const Model& model, Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  if (model.nq < kWorldCrbaFrom) {
    crba_bias_local(model, data, q.data(), qd.data(), data.nle.data());
  } else {
    crba_world(model, data, q.data());
    rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), true);
  }
  kernels::add_armature(model, data.M.data(), data.M.rows());
}

}  // namespace unchecked

const Eigen::MatrixXd& mass_matrix(const Model& model, Data& data, const Eigen::VectorXd& q) {
  check_data(model, data);
  check_q_fast(model, q);
  crba_impl(model, data, q);
  return data.M;
}

const Eigen::VectorXd& forward_dynamics_crba(const Model& model, Data& data, const Eigen::VectorXd& q,
                                             const Eigen::VectorXd& qd, const Eigen::VectorXd& tau) {
  check_forward_dynamics_arguments(model, data, q, qd, tau);
  crba_impl(model, data, q);
  // The joint transforms in data.liMi are those of this q: reuse them.
  rnea_impl<true, false>(model, data, q.data(), qd.data(), nullptr, true, data.nle.data(), true);
  data.ddq = tau - data.nle;
  if (!unchecked::solve_mass_matrix(data, data.ddq))
    throw Error("forward_dynamics: the mass matrix is not positive definite at this q "
                "(hint: a massless link at the end of a chain, or a joint that moves no mass)");
  return data.ddq;
}

}  // namespace refdyn
