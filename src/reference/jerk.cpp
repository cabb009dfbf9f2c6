// Programmed constraints of order p = 3 (jerk) and their reference dynamics (jerk.hpp).
#include "refdyn/reference/jerk.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/common/text.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>

namespace refdyn {

namespace {

// ---- forward-mode AD: dual numbers a + b ε, ε² = 0 -----------------------------------------
struct Dual {
  double v = 0, d = 0;
  Dual() = default;
  Dual(double value, double deriv = 0) : v(value), d(deriv) {}
};
inline Dual operator+(Dual a, Dual b) { return {a.v + b.v, a.d + b.d}; }
inline Dual operator-(Dual a, Dual b) { return {a.v - b.v, a.d - b.d}; }
inline Dual operator*(Dual a, Dual b) { return {a.v * b.v, a.d * b.v + a.v * b.d}; }
inline Dual sin(Dual a) { return {std::sin(a.v), std::cos(a.v) * a.d}; }
inline Dual cos(Dual a) { return {std::cos(a.v), -std::sin(a.v) * a.d}; }
inline double value(Dual a) { return a.v; }
inline double deriv(Dual a) { return a.d; }
using std::cos;
using std::sin;

/// A 3-vector and a 3×3 matrix over a scalar S (double or Dual).
template <class S>
struct V3 {
  S x{}, y{}, z{};
  S& operator[](int i) { return i == 0 ? x : i == 1 ? y : z; }
  const S& operator[](int i) const { return i == 0 ? x : i == 1 ? y : z; }
};
template <class S> V3<S> operator+(const V3<S>& a, const V3<S>& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <class S> V3<S> operator-(const V3<S>& a, const V3<S>& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class S, class T> V3<S> scale(const T& s, const V3<S>& a) { return {S(s) * a.x, S(s) * a.y, S(s) * a.z}; }
template <class S> S dot(const V3<S>& a, const V3<S>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class S> V3<S> cross(const V3<S>& a, const V3<S>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class S> V3<S> lift(const Vec3& a) { return {S(a.x()), S(a.y()), S(a.z())}; }

template <class S>
struct M3 {
  S m[3][3]{};
  static M3 identity() {
    M3 r;
    for (int i = 0; i < 3; ++i) r.m[i][i] = S(1.0);
    return r;
  }
};
template <class S> M3<S> lift(const Mat3& a) {
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = S(a(i, j));
  return r;
}
template <class S> M3<S> operator*(const M3<S>& a, const M3<S>& b) {
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
  return r;
}
template <class S> V3<S> operator*(const M3<S>& a, const V3<S>& v) {
  V3<S> r;
  for (int i = 0; i < 3; ++i) r[i] = a.m[i][0] * v.x + a.m[i][1] * v.y + a.m[i][2] * v.z;
  return r;
}
template <class S> M3<S> transpose(const M3<S>& a) {
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[j][i];
  return r;
}

/// World-frame kinematics of every body over S: pose (R, p: origin), world joint axis z,
/// angular velocity/acceleration ω, α and the origin's velocity/acceleration v, a (the base
/// accelerates with a_base: −g for inverse dynamics, 0 for kinematics).
template <class S>
struct Bodies {
  std::vector<M3<S>> R;
  std::vector<V3<S>> p, z, w, al, v, a;
};

template <class S>
void forward(const Model& model, const std::vector<S>& q, const std::vector<S>& qd, const std::vector<S>& qdd,
             const Vec3& a_base, Bodies<S>& b) {
  const int nb = model.nv;
  b.R.assign(nb, M3<S>{});
  b.p.assign(nb, V3<S>{});
  b.z = b.w = b.al = b.v = b.a = b.p;
  for (int i = 0; i < nb; ++i) {
    const int par = model.parent[i];
    const SE3& P = model.placement[i];
    const Vec3& u = model.axis[i];
    const S x = q[i] + S(model.offset[i]);
    const M3<S> Rp = par < 0 ? M3<S>::identity() : b.R[par];
    const V3<S> pp = par < 0 ? V3<S>{} : b.p[par];
    const V3<S> wp = par < 0 ? V3<S>{} : b.w[par];
    const V3<S> alp = par < 0 ? V3<S>{} : b.al[par];
    const V3<S> vp = par < 0 ? V3<S>{} : b.v[par];
    const V3<S> ap = par < 0 ? lift<S>(a_base) : b.a[par];
    const V3<S> z = Rp * lift<S>(Vec3(P.R * u));
    M3<S> Rl;
    V3<S> pl = lift<S>(P.p);
    if (model.joint_type[i] == JointType::Revolute) {
      // Rodrigues about u: c 1 + s [u]x + (1 − c) u uᵀ
      const S c = cos(x), s = sin(x), one_c = S(1.0) - c;
      M3<S> Rj;
      const double uu[3] = {u.x(), u.y(), u.z()};
      const double sk[3][3] = {{0, -u.z(), u.y()}, {u.z(), 0, -u.x()}, {-u.y(), u.x(), 0}};
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k)
          Rj.m[r][k] = (r == k ? c : S(0.0)) + s * S(sk[r][k]) + one_c * S(uu[r] * uu[k]);
      Rl = lift<S>(P.R) * Rj;
    } else {
      Rl = lift<S>(P.R);
      pl = pl + scale<S>(x, lift<S>(Vec3(P.R * u)));
    }
    b.R[i] = Rp * Rl;
    b.p[i] = pp + Rp * pl;
    b.z[i] = z;
    const V3<S> d = b.p[i] - pp;
    const V3<S> v_rigid = vp + cross(wp, d);
    const V3<S> a_rigid = ap + cross(alp, d) + cross(wp, cross(wp, d));
    if (model.joint_type[i] == JointType::Revolute) {
      b.w[i] = wp + scale<S>(qd[i], z);
      b.al[i] = alp + scale<S>(qdd[i], z) + cross(wp, scale<S>(qd[i], z));
      b.v[i] = v_rigid;
      b.a[i] = a_rigid;
    } else {
      b.w[i] = wp;
      b.al[i] = alp;
      b.v[i] = v_rigid + scale<S>(qd[i], z);
      b.a[i] = a_rigid + scale<S>(S(2.0), cross(wp, scale<S>(qd[i], z))) + scale<S>(qdd[i], z);
    }
  }
}

/// Recursive Newton–Euler in the world frame: τ = M q̈ + c + g (a_base = −g).
template <class S>
void rnea(const Model& model, const Bodies<S>& b, std::vector<S>& tau) {
  const int nb = model.nv;
  std::vector<V3<S>> F(nb), N(nb);
  for (int i = 0; i < nb; ++i) {
    const Inertia& in = model.inertia[i];
    const M3<S>& R = b.R[i];
    const V3<S> h = R * lift<S>(in.h);                       // m c (world axes)
    const M3<S> I = R * lift<S>(in.I) * transpose(R);        // about the origin, world axes
    const V3<S>& w = b.w[i];
    const V3<S>& al = b.al[i];
    const V3<S>& a = b.a[i];
    F[i] = scale<S>(in.m, a) + cross(al, h) + cross(w, cross(w, h));
    N[i] = I * al + cross(w, I * w) + cross(h, a);
  }
  tau.assign(nb, S(0.0));
  for (int i = nb - 1; i >= 0; --i) {
    tau[i] = model.joint_type[i] == JointType::Revolute ? dot(b.z[i], N[i]) : dot(b.z[i], F[i]);
    const int par = model.parent[i];
    if (par >= 0) {
      N[par] = N[par] + N[i] + cross(b.p[i] - b.p[par], F[i]);
      F[par] = F[par] + F[i];
    }
  }
}

std::vector<Dual> along(const Eigen::VectorXd& x, const Eigen::VectorXd* dx) {
  std::vector<Dual> r(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) r[i] = Dual(x[i], dx ? (*dx)[i] : 0.0);
  return r;
}

}  // namespace

void point_motion(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                  const Eigen::VectorXd& qdd, int point, PointMotion& out) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  check_vector("qdd", qdd, model.nv);
  if (point < 0 || point >= static_cast<int>(model.point_name.size()))
    throw Error(expected_got("point index", "0 .. number of points - 1", std::to_string(point)));
  const int n = model.nv;
  Bodies<Dual> b;
  forward(model, along(q, &qd), along(qd, &qdd), along(qdd, nullptr), Vec3::Zero(), b);
  out.C.setZero(3, n);
  out.Cdot.setZero(3, n);
  const int body = model.point_body[point];
  if (body < 0) {
    out.r = model.point_position[point];
    out.v = out.a = out.j = Vec3::Zero();
    return;
  }
  const V3<Dual> d = b.R[body] * lift<Dual>(model.point_position[point]);
  const V3<Dual> r = b.p[body] + d;
  const V3<Dual> v = b.v[body] + cross(b.w[body], d);
  const V3<Dual> a = b.a[body] + cross(b.al[body], d) + cross(b.w[body], cross(b.w[body], d));
  for (int k = 0; k < 3; ++k) {
    out.r[k] = value(r[k]);
    out.v[k] = value(v[k]);
    out.a[k] = value(a[k]);
    out.j[k] = deriv(a[k]);  // d/dt of a(q, q̇, q̈) with q⃛ = 0
  }
  for (int j : model.support[body]) {
    const V3<Dual> col = model.joint_type[j] == JointType::Revolute ? cross(b.z[j], r - b.p[j]) : b.z[j];
    for (int k = 0; k < 3; ++k) {
      out.C(k, j) = value(col[k]);
      out.Cdot(k, j) = deriv(col[k]);
    }
  }
}

void inverse_dynamics_rate(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                           const Eigen::VectorXd& qdd, Eigen::VectorXd& tau, Eigen::VectorXd& tau_rate) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  check_vector("qdd", qdd, model.nv);
  Bodies<Dual> b;
  forward(model, along(q, &qd), along(qd, &qdd), along(qdd, nullptr), Vec3(-model.gravity), b);
  std::vector<Dual> t;
  rnea(model, b, t);
  tau.resize(model.nv);
  tau_rate.resize(model.nv);
  for (int i = 0; i < model.nv; ++i) {
    tau[i] = t[i].v;
    tau_rate[i] = t[i].d;
  }
}

// ---- the jerk-level expression constraint ----------------------------------------------------

namespace {
enum class JVar { X, V, A, J, Q, QD, QDD, QDDD, T };
struct JerkVar {
  JVar kind;
  int index = 0;
  int axis = 0;
};
bool is_point_var(JVar k) { return k == JVar::X || k == JVar::V || k == JVar::A || k == JVar::J; }
bool is_jerk(JVar k) { return k == JVar::J || k == JVar::QDDD; }
bool is_acc(JVar k) { return k == JVar::A || k == JVar::QDD; }
}  // namespace

struct JerkConstraint::Impl {
  std::vector<JerkVar> vars;
  std::unique_ptr<Expression> expr;
};

JerkConstraint::~JerkConstraint() = default;

JerkConstraint::JerkConstraint(const Model& m, const std::string& name, const std::string& text,
                               const std::map<std::string, double>& params)
    : name_(name), text_(text), impl_(std::make_unique<Impl>()) {
  std::vector<std::string> names;
  std::vector<JerkVar> all;
  const char* ax[] = {"x", "y", "z"};
  const char* pre[] = {"", "v", "a", "j"};
  const JVar pk[] = {JVar::X, JVar::V, JVar::A, JVar::J};
  for (size_t p = 0; p < m.point_name.size(); ++p)
    for (int l = 0; l < 4; ++l)
      for (int a = 0; a < 3; ++a) {
        names.push_back(std::string(pre[l]) + ax[a] + "(" + m.point_name[p] + ")");
        all.push_back({pk[l], static_cast<int>(p), a});
      }
  const char* jn[] = {"q", "qd", "qdd", "qddd"};
  const JVar jk[] = {JVar::Q, JVar::QD, JVar::QDD, JVar::QDDD};
  for (int j = 0; j < m.nq; ++j)
    for (int l = 0; l < 4; ++l) {
      names.push_back(std::string(jn[l]) + "(" + m.joint_name[j] + ")");
      all.push_back({jk[l], j, 0});
    }
  names.push_back("t");
  all.push_back({JVar::T, 0, 0});
  std::unique_ptr<Expression> probe;
  try {
    probe = std::make_unique<Expression>(text, names, params, 0);
  } catch (const Error& e) {
    throw Error("constraint '" + name + "': " + e.what());
  }
  bool jerk = false;
  for (int k : probe->used_variables()) jerk = jerk || is_jerk(all[k].kind);
  if (!jerk)
    throw Error("constraint '" + name + "': order: jerk, but the expression (after substituting the parameters: " +
                probe->text() + ") involves no jerk jx(P), jy(P), jz(P) or qddd(j) (hint: write it at a lower order)");
  std::vector<std::string> used;
  for (int k : probe->referenced_variables()) {
    used.push_back(names[k]);
    impl_->vars.push_back(all[k]);
    if (is_point_var(all[k].kind) &&
        std::find(points_.begin(), points_.end(), all[k].index) == points_.end())
      points_.push_back(all[k].index);
  }
  impl_->expr = std::make_unique<Expression>(text, used, params, 2);
  const auto& v = impl_->vars;
  for (size_t i = 0; i < v.size(); ++i)
    for (size_t j = 0; j < v.size(); ++j) {
      if (!is_jerk(v[i].kind) || !(is_jerk(v[j].kind) || is_acc(v[j].kind))) continue;
      const std::string d2 = impl_->expr->second_derivative_text(static_cast<int>(i), static_cast<int>(j));
      if (d2 == "0") continue;
      throw Error("constraint '" + name + "': order: jerk expects an expression linear in the jerks whose "
                  "coefficients do not depend on accelerations or jerks (B(t, q, qd) qddd + s = 0), but d2f/d" +
                  used[i] + "d" + used[j] + " = " + d2 + " is not zero");
    }
}

void JerkConstraint::evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                              const Eigen::VectorXd& qdd, const std::vector<PointMotion>& pts, double& s,
                              Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> B, Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> Bdot) const {
  const auto& vars = impl_->vars;
  const size_t n = vars.size();
  std::vector<double> w(n), wd(n), grad(n), hess(n * n);
  for (size_t k = 0; k < n; ++k) {
    const JerkVar& v = vars[k];
    const PointMotion* P = is_point_var(v.kind) ? &pts[v.index] : nullptr;
    switch (v.kind) {
      case JVar::X: w[k] = P->r[v.axis], wd[k] = P->v[v.axis]; break;
      case JVar::V: w[k] = P->v[v.axis], wd[k] = P->a[v.axis]; break;
      case JVar::A: w[k] = P->a[v.axis], wd[k] = 0; break;  // f_kl = 0 for jerk k, acceleration l
      case JVar::J: w[k] = P->j[v.axis], wd[k] = 0; break;
      case JVar::Q: w[k] = q[v.index], wd[k] = qd[v.index]; break;
      case JVar::QD: w[k] = qd[v.index], wd[k] = qdd[v.index]; break;
      case JVar::QDD: w[k] = qdd[v.index], wd[k] = 0; break;
      case JVar::QDDD: w[k] = 0, wd[k] = 0; break;
      case JVar::T: w[k] = t, wd[k] = 1; break;
    }
  }
  impl_->expr->evaluate(w.data(), s, grad.data(), hess.data());
  B.setZero();
  Bdot.setZero();
  for (size_t k = 0; k < n; ++k) {
    const JerkVar& v = vars[k];
    if (!is_jerk(v.kind)) continue;
    double fk_dot = 0;  // d/dt ∂f/∂w_k along the motion
    for (size_t l = 0; l < n; ++l) fk_dot += hess[k * n + l] * wd[l];
    if (v.kind == JVar::QDDD) {
      B[v.index] += grad[k];
      Bdot[v.index] += fk_dot;
    } else {
      const PointMotion& P = pts[v.index];
      B += grad[k] * P.C.row(v.axis);
      Bdot += fk_dot * P.C.row(v.axis) + grad[k] * P.Cdot.row(v.axis);
    }
  }
}

// ---- the reference dynamics of jerk constraints ----------------------------------------------

JerkDynamics::JerkDynamics(const Model& model, std::vector<JerkConstraintPtr> constraints, JerkDynamicsOptions options,
                           const ForceSet* forces)
    : model_(model), forces_(forces), constraints_(std::move(constraints)), opt_(options), n_(model.nv),
      m_(static_cast<int>(constraints_.size())), data_(model) {
  if (forces_) {
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n_);
    Eigen::VectorXd rate = Eigen::VectorXd::Zero(n_);
    for (const auto& e : forces_->elements())
      if (e->num_states() > 0 || !e->add_rate(0.0, zero, zero, zero, rate))
        throw Error("force element '" + e->name() + "' cannot be used with jerk constraints (order: jerk): " +
                    (e->num_states() > 0 ? std::string("it has states")
                                         : std::string("it does not provide the time derivative of its force")) +
                    " (damping, spring, effort and flexible_drive do)");
  }
  if (!(std::isfinite(opt_.kappa) && opt_.kappa >= 0))
    throw Error(expected_got("jerk dynamics option kappa", "a finite value >= 0 [1/s]", fmt(opt_.kappa)));
  if (m_ > n_)
    throw Error(expected_got("number of jerk constraint rows", "at most the number of coordinates (" +
                                                                    std::to_string(n_) + ")",
                             std::to_string(m_)));
  for (const auto& c : constraints_)
    for (int p : c->points())
      if (std::find(points_.begin(), points_.end(), p) == points_.end()) points_.push_back(p);
  motion_.resize(model.point_name.size());
  B_.setZero(m_, n_);
  Bdot_.setZero(m_, n_);
  s_.setZero(m_);
  row_res_.setZero(m_);
  lambda_.setZero(m_);
}

namespace {
/// λ = (B M⁻¹ Bᵀ)⁻¹ B M⁻¹ R (the part of R along the rows, in the metric M⁻¹).
bool multipliers(const Eigen::MatrixXd& M, const Eigen::MatrixXd& B, const Eigen::VectorXd& R, Eigen::VectorXd& lambda,
                 Eigen::LLT<Eigen::MatrixXd>& llt) {
  llt.compute(M);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::MatrixXd Y = llt.solve(B.transpose());
  const Eigen::MatrixXd S = B * Y;
  Eigen::LLT<Eigen::MatrixXd> ls(S);
  if (ls.info() != Eigen::Success) return false;
  lambda = ls.solve(Y.transpose() * R);
  return true;
}
}  // namespace

void JerkDynamics::forces_and_rates(double t) {
  Q_.setZero(n_);
  Qdot_.setZero(n_);
  if (!forces_ || forces_->elements().empty()) return;
  double z = 0, zdot = 0;  // the elements have no states (checked by the constructor)
  forces_->evaluate(t, q_, qd_, &z, Q_, &zdot);
  for (const auto& e : forces_->elements()) e->add_rate(t, q_, qd_, qdd_, Qdot_);
}

Eigen::VectorXd JerkDynamics::initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                            const Eigen::VectorXd* qdd_hint) {
  model_.check_q(q0);
  check_vector("qd", qd0, n_);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n_);
  Eigen::VectorXd tau, taud;
  inverse_dynamics_rate(model_, q0, qd0, zero, tau, taud);  // τ(q̈ = 0) = c + g
  q_ = q0;
  qd_ = qd0;
  qdd_ = zero;
  forces_and_rates(t0);  // Q does not depend on q̈
  const Eigen::MatrixXd M = mass_matrix(model_, data_, q0);
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success)
    throw NumericalFailure(t0, "at t0 = " + fmt(t0) + " s the mass matrix is not positive definite (a joint that "
                               "moves no mass or inertia?)");
  Eigen::VectorXd qdd0 = llt.solve(Q_ - tau);  // the free acceleration M⁻¹F, F = Q − c − g
  if (qdd_hint && m_ > 0) {
    check_vector("qdd", *qdd_hint, n_);
    for (int p : points_) point_motion(model_, q0, qd0, qdd0, p, motion_[p]);
    for (int r = 0; r < m_; ++r) {
      double s;
      constraints_[r]->evaluate(t0, q0, qd0, qdd0, motion_, s, B_.row(r), Bdot_.row(r));
    }
    Eigen::VectorXd lambda0;
    Eigen::LLT<Eigen::MatrixXd> l2;
    if (!multipliers(M, B_, M * (*qdd_hint - qdd0), lambda0, l2))
      throw NumericalFailure(t0, "at t0 = " + fmt(t0) + " s the jerk constraint rows are linearly dependent");
    qdd0 += llt.solve(B_.transpose() * lambda0);
  }
  Eigen::VectorXd x(3 * n_);
  x << q0, qd0, qdd0;
  return x;
}

void JerkDynamics::derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  check_size("x", state_size(), x.size(), "x = [q; qd; qdd]");
  if (!x.allFinite()) throw NumericalFailure(t, "at t = " + fmt(t) + " s the state is not finite (NaN or infinity)");
  q_ = x.head(n_);
  qd_ = x.segment(n_, n_);
  qdd_ = x.segment(2 * n_, n_);
  for (int p : points_) point_motion(model_, q_, qd_, qdd_, p, motion_[p]);
  for (int r = 0; r < m_; ++r) constraints_[r]->evaluate(t, q_, qd_, qdd_, motion_, s_[r], B_.row(r), Bdot_.row(r));
  inverse_dynamics_rate(model_, q_, qd_, qdd_, tau_, taud_);
  forces_and_rates(t);
  R_ = tau_ - Q_;       // M q̈ − F, F = Q − c − g
  taud_ -= Qdot_;       // Ṙ at q⃛ = 0
  const Eigen::MatrixXd M = mass_matrix(model_, data_, q_);
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite (a joint that moves "
                              "no mass or inertia?)");
  if (m_ > 0) {
    if (!multipliers(M, B_, R_, lambda_, llt))  // R = Bᵀλ + ρ here; stored below with the sign of
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the jerk constraint rows are linearly dependent (B M⁻¹ Bᵀ is "
                                "singular)");
  } else {
    llt.compute(M);
  }
  dyn_res_ = m_ ? (R_ - B_.transpose() * lambda_).cwiseAbs().maxCoeff() : R_.cwiseAbs().maxCoeff();
  // KKT: [M, −Bᵀ; B, 0] [q⃛; ν] = [Ḃᵀλ − τ̇ − κR; −s]  (λ with R = Bᵀλ + ρ)
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n_ + m_, n_ + m_);
  K.topLeftCorner(n_, n_) = M;
  K.topRightCorner(n_, m_) = -B_.transpose();
  K.bottomLeftCorner(m_, n_) = B_;
  Eigen::VectorXd rhs(n_ + m_);
  rhs.head(n_) = Bdot_.transpose() * lambda_ - taud_ - opt_.kappa * R_;
  rhs.tail(m_) = -s_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(K);
  const Eigen::VectorXd sol = lu.solve(rhs);
  if (!sol.allFinite()) throw NumericalFailure(t, "at t = " + fmt(t) + " s the jerk-level system is singular");
  qddd_ = sol.head(n_);
  row_res_ = B_ * qddd_ + s_;
  lambda_ = -lambda_;  // ReferenceDynamics' sign: Q_c = M q̈ − F = −Bᵀλ
  xdot.resize(3 * n_);
  xdot << qd_, qdd_, qddd_;
}

namespace {
class JerkRow final : public Constraint {
 public:
  explicit JerkRow(JerkConstraintPtr c) : c_(std::move(c)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  int order() const override { return 3; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {}; }
  std::string describe() const override { return c_->text() + " = 0"; }
  void evaluate(const ConstraintInput&, Eigen::Ref<Eigen::VectorXd>, Eigen::Ref<Eigen::VectorXd>,
                Eigen::Ref<Eigen::MatrixXd>, Eigen::Ref<Eigen::VectorXd>) const override {
    throw Error("constraint '" + name + "' is jerk-level (order: jerk): it is evaluated by JerkDynamics, not by "
                "evaluate_constraints / ReferenceDynamics");
  }
  const JerkConstraintPtr& jerk() const { return c_; }

 private:
  JerkConstraintPtr c_;
};
}  // namespace

ConstraintPtr jerk_expression_constraint(const Model& model, const std::string& name, const std::string& text,
                                         const std::map<std::string, double>& parameters, ConstraintOrigin origin) {
  if (name.empty()) throw Error("jerk_expression_constraint: expected a name, got an empty one");
  auto c = std::make_shared<JerkRow>(std::make_shared<JerkConstraint>(model, name, text, parameters));
  c->name = name;
  c->origin = origin;
  return c;
}

JerkConstraintPtr jerk_constraint_of(const Constraint& c) {
  const auto* r = dynamic_cast<const JerkRow*>(&c);
  return r ? r->jerk() : nullptr;
}

}  // namespace refdyn
