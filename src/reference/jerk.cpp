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
#include "refdyn/constraints/constraints.hpp"

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
  std::vector<JerkVar> vars, source_vars;
  std::unique_ptr<Expression> expr, source;
};

JerkConstraint::~JerkConstraint() = default;

JerkConstraint::JerkConstraint(const Model& m, const std::string& name, const std::string& text,
                               const std::map<std::string, double>& params, const std::string& source_text)
    : name_(name), text_(text), source_text_(source_text), impl_(std::make_unique<Impl>()) {
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
  if (!source_text.empty()) {
    std::unique_ptr<Expression> src;
    try {
      src = std::make_unique<Expression>(source_text, names, params, 0);
    } catch (const Error& e) {
      throw Error("constraint '" + name + "': " + e.what());
    }
    std::vector<std::string> src_used;
    for (int k : src->referenced_variables()) {
      if (is_jerk(all[k].kind))
        throw Error("constraint '" + name + "': its source expression (differentiate: true) involves the jerk " +
                    names[k] + ": write the source at the acceleration level");
      src_used.push_back(names[k]);
      impl_->source_vars.push_back(all[k]);
      if (is_point_var(all[k].kind) &&
          std::find(points_.begin(), points_.end(), all[k].index) == points_.end())
        points_.push_back(all[k].index);
    }
    impl_->source = std::make_unique<Expression>(source_text, src_used, params, 0);
  }
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

double JerkConstraint::source_value(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                   const std::vector<PointMotion>& pts) const {
  if (!impl_->source) throw Error("constraint '" + name_ + "' has no source expression (differentiate: true)");
  const auto& vars = impl_->source_vars;
  std::vector<double> w(vars.size());
  for (size_t k = 0; k < vars.size(); ++k) {
    const JerkVar& v = vars[k];
    switch (v.kind) {
      case JVar::X: w[k] = pts[v.index].r[v.axis]; break;
      case JVar::V: w[k] = pts[v.index].v[v.axis]; break;
      case JVar::A: w[k] = pts[v.index].a[v.axis]; break;  // the drift (q̈ = 0)
      case JVar::Q: w[k] = q[v.index]; break;
      case JVar::QD: w[k] = qd[v.index]; break;
      case JVar::T: w[k] = t; break;
      default: w[k] = 0; break;  // qdd(j) = 0 (jerks were rejected)
    }
  }
  return impl_->source->value(w.data());
}

NewConstraint differentiated_jerk_constraint(const Model& model, const std::string& name,
                                             const std::string& acceleration_text,
                                             const std::map<std::string, double>& parameters, ConstraintOrigin origin) {
  const std::string text = differentiate_expression_text(model, name, acceleration_text, parameters);
  return jerk_expression_constraint(model, name, text, parameters, origin, acceleration_text);
}

// ---- the reference dynamics of jerk constraints ----------------------------------------------

/// The rows of order ≤ 2 over dual numbers along the motion (one direction: t → 1, q → q̇, q̇ → q̈).
struct JerkDynamics::DualRows {
  DualRows(const Model& model, const ConstraintSet& set) : ev(model, set), q(model.nv), qd(model.nv) {}
  ConstraintEvalDual ev;
  std::vector<JacobianScalar> q, qd;
};

JerkDynamics::~JerkDynamics() = default;

JerkDynamics::JerkDynamics(const Model& model, std::vector<JerkConstraintPtr> constraints, JerkDynamicsOptions options,
                           const ForceSet* forces)
    : model_(model), forces_(forces), constraints_(std::move(constraints)), opt_(std::move(options)), n_(model.nv),
      m_(static_cast<int>(constraints_.size())), data_(model) {
  for (int r = 0; r < m_; ++r) jerk_row_.push_back(r);
  setup();
}

JerkDynamics::JerkDynamics(const Model& model, const ConstraintSet& rows, JerkDynamicsOptions options,
                           const ForceSet* forces)
    : model_(model), forces_(forces), opt_(std::move(options)), n_(model.nv), m_(rows.rows()), data_(model) {
  all_ = rows;
  for (const ConstraintPtr& c : rows.constraints()) {
    if (JerkConstraintPtr j = jerk_constraint_of(*c)) {
      jerk_row_.push_back(rows.row_offset(static_cast<int>(&c - rows.constraints().data())));
      constraints_.push_back(std::move(j));
      continue;
    }
    if (c->order() > 2)
      throw Error("constraint '" + c->name + "' is of order " + std::to_string(c->order()) +
                  " but not a jerk expression row: the jerk-level reference dynamics takes rows of order <= 3");
    const int off = rows.row_offset(static_cast<int>(&c - rows.constraints().data()));
    for (int i = 0; i < c->rows(); ++i) {
      lower_row_.push_back(off + i);
      lower_order_.push_back(static_cast<char>(c->order()));
    }
    lower_.add(c);
  }
  setup();
}

void JerkDynamics::setup() {
  if (forces_) {
    nz_ = forces_->num_states();
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n_);
    Eigen::VectorXd rate = Eigen::VectorXd::Zero(n_);
    std::vector<double> z(std::max(1, nz_), 0.0);
    for (size_t k = 0; k < forces_->elements().size(); ++k) {
      const auto& e = forces_->elements()[k];
      const double* zk = z.data() + forces_->state_offset(static_cast<int>(k));
      if (!e->add_rate_with_states(0.0, zero, zero, zero, zk, zk, rate))
        throw Error("force element '" + e->name() + "' cannot be used with jerk constraints (order: jerk): it does not "
                    "provide the time derivative of its force (damping, spring, effort, flexible_drive and lugre do)");
    }
  }
  if (!(std::isfinite(opt_.kappa) && opt_.kappa >= 0))
    throw Error(expected_got("jerk dynamics option kappa", "a finite value >= 0 [1/s]", fmt(opt_.kappa)));
  for (double g : {opt_.alpha, opt_.beta, opt_.beta_first_order})
    if (!(std::isfinite(g) && g >= 0))
      throw Error(expected_got("jerk dynamics Baumgarte gain", "a finite value >= 0 [1/s]", fmt(g)));
  if (m_ > n_)
    throw Error(expected_got("number of constraint rows of a jerk-level problem",
                             "at most the number of coordinates (" + std::to_string(n_) + ")", std::to_string(m_)));
  for (const std::string& name : opt_.consistent_with) {
    const auto it = std::find_if(constraints_.begin(), constraints_.end(),
                                 [&](const JerkConstraintPtr& c) { return c->name() == name; });
    if (it == constraints_.end())
      throw Error("consistent_with: '" + name + "' is not a jerk constraint row of this problem");
    if ((*it)->source_text().empty())
      throw Error("consistent_with: jerk row '" + name + "' was not differentiated from an acceleration row "
                  "(differentiate: true), so there is no acceleration row to be consistent with");
  }
  for (const auto& c : constraints_)
    for (int p : c->points())
      if (std::find(points_.begin(), points_.end(), p) == points_.end()) points_.push_back(p);
  motion_.resize(model_.point_name.size());
  if (lower_.rows() > 0) dual_ = std::make_unique<DualRows>(model_, lower_);
  B_.setZero(m_, n_);
  Bdot_.setZero(m_, n_);
  s_.setZero(m_);
  psi_.setZero(m_);
  row_res_.setZero(m_);
  row_rate_.setZero(m_);
  lambda_.setZero(m_);
  zdot_.setZero(nz_);
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

void JerkDynamics::forces_and_rates(double t, const double* z) {
  Q_.setZero(n_);
  Qdot_.setZero(n_);
  zdot_.setZero(nz_);
  if (!forces_ || forces_->elements().empty()) return;
  double none = 0;
  forces_->evaluate(t, q_, qd_, nz_ ? z : &none, Q_, nz_ ? zdot_.data() : &none);
  for (size_t k = 0; k < forces_->elements().size(); ++k) {
    const int off = forces_->state_offset(static_cast<int>(k));
    forces_->elements()[k]->add_rate_with_states(t, q_, qd_, qdd_, nz_ ? z + off : nullptr,
                                                 nz_ ? zdot_.data() + off : nullptr, Qdot_);
  }
}

void JerkDynamics::evaluate_rows(double t) {
  // Jerk rows: s, B, Ḃ from the point motions.
  for (int p : points_) point_motion(model_, q_, qd_, qdd_, p, motion_[p]);
  for (size_t k = 0; k < constraints_.size(); ++k) {
    const int r = jerk_row_[k];
    constraints_[k]->evaluate(t, q_, qd_, qdd_, motion_, s_[r], B_.row(r), Bdot_.row(r));
  }
  if (!dual_) return;
  // Rows of order ≤ 2: their stabilized acceleration level ψ(t, q, q̇, q̈) = A q̈ + γ + (Baumgarte)
  // and its rate along the motion at q⃛ = 0, from one dual evaluation seeded t → 1, q → q̇, q̇ → q̈.
  DualRows& d = *dual_;
  for (int i = 0; i < n_; ++i) {
    d.q[i] = JacobianScalar::variable(q_[i], 0, qd_[i]);
    d.qd[i] = JacobianScalar::variable(qd_[i], 0, qdd_[i]);
  }
  evaluate_constraints_dual(model_, lower_, d.ev, t /*DUALTIME*/, d.q.data(), d.qd.data());
  const double kd = 2.0 * opt_.alpha, kp = opt_.beta * opt_.beta, k1 = opt_.beta_first_order;
  for (size_t i = 0; i < lower_row_.size(); ++i) {
    const int r = lower_row_[i];
    const JacobianScalar* A = d.ev.A.data() + i * static_cast<size_t>(n_);
    double psi = d.ev.gamma[i].v, psid = d.ev.gamma[i].d[0];
    for (int j = 0; j < n_; ++j) {
      B_(r, j) = A[j].v;
      Bdot_(r, j) = A[j].d[0];
      psi += A[j].v * qdd_[j];
      psid += A[j].d[0] * qdd_[j];
    }
    const JacobianScalar& phi = d.ev.phi[i];
    const JacobianScalar& phid = d.ev.phid[i];
    switch (lower_order_[i]) {
      case 0:  // Φ̈ + 2αΦ̇ + β²Φ
        psi += kd * phid.v + kp * phi.v;
        psid += kd * phid.d[0] + kp * phi.d[0];
        row_res_[r] = phi.v;
        row_rate_[r] = phid.v;
        break;
      case 1:  // ċ + β₁c (c is stored in phi)
        psi += k1 * phi.v;
        psid += k1 * phi.d[0];
        row_res_[r] = row_rate_[r] = phi.v;
        break;
      default:  // B q̈ + s
        row_res_[r] = row_rate_[r] = psi;
        break;
    }
    psi_[r] = psi;
    s_[r] = psid + opt_.kappa * psi;  // A q⃛ = −(ψ̇ + κψ)
  }
}

Eigen::VectorXd JerkDynamics::initial_state(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& qd0,
                                            const Eigen::VectorXd* qdd_hint, const Eigen::VectorXd* z0) {
  model_.check_q(q0);
  check_vector("qd", qd0, n_);
  if (qdd_hint) check_vector("qdd", *qdd_hint, n_);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(nz_);
  if (z0) {
    check_vector("z0", *z0, nz_);
    z = *z0;
  }
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n_);
  Eigen::VectorXd tau, taud;
  inverse_dynamics_rate(model_, q0, qd0, zero, tau, taud);  // τ(q̈ = 0) = c + g
  q_ = q0;
  qd_ = qd0;
  qdd_ = zero;
  forces_and_rates(t0, z.data());  // Q does not depend on q̈
  const Eigen::MatrixXd M = mass_matrix(model_, data_, q0);
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success)
    throw NumericalFailure(t0, "at t0 = " + fmt(t0) + " s the mass matrix is not positive definite (a joint that "
                               "moves no mass or inertia?)");
  Eigen::VectorXd qdd0 = llt.solve(Q_ - tau);  // the free acceleration a0 = M⁻¹F, F = Q − c − g
  if (m_ > 0) {
    // q̈0 = a0 + Y λ0, Y = M⁻¹Gᵀ; one linear condition per row (see the header). G and the rows'
    // acceleration levels do not depend on q̈ (ψ is affine in q̈: evaluated at q̈ = 0 it is its constant part).
    evaluate_rows(t0);
    const Eigen::MatrixXd Y = llt.solve(B_.transpose());
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(m_, m_);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(m_);
    for (size_t i = 0; i < lower_row_.size(); ++i) {  // ψ(q̈0) = ψ(0) + A q̈0 = 0
      const int r = lower_row_[i];
      S.row(r) = B_.row(r) * Y;
      b[r] = -psi_[r] - B_.row(r).dot(qdd0);
    }
    for (size_t k = 0; k < constraints_.size(); ++k) {
      const int r = jerk_row_[k];
      const JerkConstraint& c = *constraints_[k];
      if (std::find(opt_.consistent_with.begin(), opt_.consistent_with.end(), c.name()) != opt_.consistent_with.end()) {
        // the source row B q̈ + s_acc = 0 (its B is the jerk row's: ∂ḟ/∂q⃛ = ∂f/∂q̈)
        const double s_acc = c.source_value(t0, q0, qd0, motion_);
        S.row(r) = B_.row(r) * Y;
        b[r] = -s_acc - B_.row(r).dot(qdd0);
      } else if (qdd_hint) {
        S.row(r) = B_.row(r) * Y;
        b[r] = B_.row(r).dot(*qdd_hint - qdd0);
      } else {
        S(r, r) = 1.0;  // λ0 = 0
      }
    }
    Eigen::FullPivLU<Eigen::MatrixXd> lu(S);
    if (!lu.isInvertible())
      throw NumericalFailure(t0, "at t0 = " + fmt(t0) + " s the constraint rows are linearly dependent (G M⁻¹ Gᵀ is "
                                 "singular): no consistent initial acceleration");
    qdd0 += Y * lu.solve(b);
  }
  Eigen::VectorXd x(state_size());
  x << q0, qd0, qdd0, z;
  return x;
}

void JerkDynamics::derivative(double t, const Eigen::VectorXd& x, Eigen::VectorXd& xdot) {
  check_size("x", state_size(), x.size(), "x = [q; qd; qdd; z]");
  if (!x.allFinite()) throw NumericalFailure(t, "at t = " + fmt(t) + " s the state is not finite (NaN or infinity)");
  q_ = x.head(n_);
  qd_ = x.segment(n_, n_);
  qdd_ = x.segment(2 * n_, n_);
  evaluate_rows(t);
  inverse_dynamics_rate(model_, q_, qd_, qdd_, tau_, taud_);
  forces_and_rates(t, x.data() + 3 * n_);
  R_ = tau_ - Q_;       // M q̈ − F, F = Q − c − g
  taud_ -= Qdot_;       // Ṙ at q⃛ = 0
  const Eigen::MatrixXd M = mass_matrix(model_, data_, q_);
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success)
    throw NumericalFailure(t, "at t = " + fmt(t) + " s the mass matrix is not positive definite (a joint that moves "
                              "no mass or inertia?)");
  if (m_ > 0) {
    if (!multipliers(M, B_, R_, lambda_, llt))  // R = Gᵀλ + ρ here; stored below with the sign of
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the constraint rows are linearly dependent (G M⁻¹ Gᵀ is "
                                "singular: redundant rows or a singular configuration)");
  } else {
    llt.compute(M);
  }
  dyn_res_ = m_ ? (R_ - B_.transpose() * lambda_).cwiseAbs().maxCoeff() : R_.cwiseAbs().maxCoeff();
  // KKT: [M, −Gᵀ; G, 0] [q⃛; ν] = [Ġᵀλ − Ṙ − κR; −s]  (λ with R = Gᵀλ + ρ)
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
  for (int r : jerk_row_) row_res_[r] = row_rate_[r] = B_.row(r).dot(qddd_) + s_[r];
  lambda_ = -lambda_;  // ReferenceDynamics' sign: Q_c = M q̈ − F = −Gᵀλ
  xdot.resize(state_size());
  xdot << qd_, qdd_, qddd_, zdot_;
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
                                         const std::map<std::string, double>& parameters, ConstraintOrigin origin,
                                         const std::string& source_text) {
  if (name.empty()) throw Error("jerk_expression_constraint: expected a name, got an empty one");
  auto c = std::make_shared<JerkRow>(std::make_shared<JerkConstraint>(model, name, text, parameters, source_text));
  c->name = name;
  c->origin = origin;
  return c;
}

JerkConstraintPtr jerk_constraint_of(const Constraint& c) {
  const auto* r = dynamic_cast<const JerkRow*>(&c);
  return r ? r->jerk() : nullptr;
}

}  // namespace refdyn
