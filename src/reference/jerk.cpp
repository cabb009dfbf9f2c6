// Programmed constraints of order p = 3 (jerk) and their reference dynamics (jerk.hpp).
#include "refdyn/reference/jerk.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/expression/expression.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/dual.hpp"
#include "refdyn/multibody/generic_dynamics.hpp"
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

// Exact time derivatives along the motion: the generic multibody core over one-direction dual
// numbers, seeded with q + q̇ ε, q̇ + q̈ ε, q̈ + 0 ε (q⃛ = 0).
using D1 = multibody::Dual<1>;

struct DualMotion {
  std::uint64_t model_id = 0;        ///< the model `bodies` were converted from (ids are unique)
  multibody::Bodies<D1> bodies;
  multibody::Poses<D1> poses;
  multibody::Motions<D1> motion;
  multibody::NewtonEulerWork<D1> work;
  std::vector<D1> q, qd, qdd, tau;
};

void seed(const Eigen::VectorXd& x, const Eigen::VectorXd* dx, std::vector<D1>& out) {
  out.resize(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) out[i] = D1::variable(x[i], 0, dx ? (*dx)[i] : 0.0);
}

/// This thread's workspace with the model's bodies over D1 and their poses at q + q̇ ε (a Model
/// is immutable and its id unique, so the converted bodies are kept until another model comes).
DualMotion& dual_state(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                       const Eigen::VectorXd& qdd) {
  thread_local DualMotion m;
  if (m.model_id != model.id || m.bodies.size() != model.nv) {
    m.bodies = multibody::bodies_from_model<D1>(model);
    m.model_id = model.id;
  }
  seed(q, &qd, m.q);
  seed(qd, &qdd, m.qd);
  seed(qdd, nullptr, m.qdd);
  multibody::forward_poses(m.bodies, m.q, m.poses);
  return m;
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
  out.C.setZero(3, n);
  out.Cdot.setZero(3, n);
  const int body = model.point_body[point];
  if (body < 0) {
    out.r = model.point_position[point];
    out.v = out.a = out.j = Vec3::Zero();
    return;
  }
  DualMotion& m = dual_state(model, q, qd, qdd);
  multibody::forward_motion(m.bodies, m.poses, m.qd.data(), m.qdd.data(), multibody::zero3<D1>(), true, m.motion);
  const multibody::PointKinematics<D1> k = multibody::point_kinematics(m.bodies.points[point], m.poses, m.motion);
  for (int i = 0; i < 3; ++i) {
    out.r[i] = k.r[i].v;
    out.v[i] = k.v[i].v;
    out.a[i] = k.a[i].v;
    out.j[i] = k.a[i].d[0];  // d/dt of a(q, q̇, q̈) with q⃛ = 0
  }
  for (int j : model.support[body]) {
    const multibody::Vec3T<D1> col = multibody::point_jacobian_column(m.bodies, m.poses, j, k.r);
    for (int i = 0; i < 3; ++i) {
      out.C(i, j) = col[i].v;
      out.Cdot(i, j) = col[i].d[0];
    }
  }
}

void inverse_dynamics_rate(const Model& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                           const Eigen::VectorXd& qdd, Eigen::VectorXd& tau, Eigen::VectorXd& tau_rate) {
  model.check_q(q);
  check_vector("qd", qd, model.nv);
  check_vector("qdd", qdd, model.nv);
  DualMotion& m = dual_state(model, q, qd, qdd);
  multibody::inverse_dynamics(m.bodies, m.poses, model.gravity, m.qd.data(), m.qdd.data(), true, m.work, m.tau);
  const std::vector<D1>& t = m.tau;
  tau.resize(model.nv);
  tau_rate.resize(model.nv);
  for (int i = 0; i < model.nv; ++i) {
    tau[i] = t[i].v;
    tau_rate[i] = t[i].d[0];
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

NewConstraint jerk_expression_constraint(const Model& model, const std::string& name, const std::string& text,
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
