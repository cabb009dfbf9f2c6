#include "refdyn/constraints/constraints.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/common/text.hpp"

#include <algorithm>
#include <cmath>

namespace refdyn {

const char* to_string(ConstraintOrigin o) { return o == ConstraintOrigin::Material ? "material" : "programmed"; }

const char* order_label(int order) {
  switch (order) {
    case 0: return "holonomic (position)";
    case 1: return "first order (velocity)";
    case 2: return "acceleration (order 2)";
    case 3: return "jerk (order 3)";
    default: return "unknown";
  }
}

double TaskGeometry::value(const std::string& k) const {
  for (const auto& [name, v] : values)
    if (name == k) return v;
  return std::nan("");
}

// Dual-number evaluation (evaluate_dual, eval_dual): the same formulas as the double code next
// to each, over JacobianScalar with the arrays of linear3.hpp; the double code is left as it was
// (its results are compared bit for bit by the paper study).
using JS = JacobianScalar;
using V3D = multibody::Vec3T<JS>;
using M3D = multibody::Mat3T<JS>;

void Constraint::evaluate_dual(const ConstraintInputDual&, JS*, JS*, JS*, JS*) const {
  throw Error("constraint '" + name + "' (" + describe() +
              ") has no exact derivatives: its kind does not implement evaluate_dual (hint: an implicit "
              "integrator's exact Jacobian needs it; use an explicit integrator, or write the constraint as an "
              "expression constraint)");
}

ImplicitSurface::ValueDual ImplicitSurface::eval_dual(const V3D&, const JS&) const {
  throw Error("surface " + describe() +
              " has no exact derivatives: its kind does not implement eval_dual (hint: an implicit integrator's "
              "exact Jacobian needs it; use an explicit integrator)");
}

namespace {

/// −x with derivative parts 0 − x.d (never −0): for a constant x the bits of JS(−x.v), which the
/// double-time code wrote, so an unseeded time gives its results bit for bit.
JS negated(const JS& x) {
  JS r(-x.v);
  for (int k = 0; k < kJacobianDirections; ++k) r.d[k] = 0.0 - x.d[k];
  return r;
}

ImplicitSurface::ValueDual zero_surface_value() {
  ImplicitSurface::ValueDual v;
  v.f = v.ft = v.ftt = JS(0.0);
  v.grad = v.grad_t = multibody::zero3<JS>();
  v.hess = multibody::zero33<JS>();
  return v;
}

// ---------------- surfaces ----------------
class EllipticCylinder final : public ImplicitSurface {
 public:
  EllipticCylinder(Number a, Number b, Number cx, Number cy)
      : ia2_(1 / (a * a)), ib2_(1 / (b * b)), a_(std::move(a)), b_(std::move(b)), cx_(std::move(cx)), cy_(std::move(cy)) {}
  Value eval(const Vec3& r, double) const override {
    const double x = r.x() - cx_.value, y = r.y() - cy_.value;
    Value v;
    v.f = x * x * ia2_ + y * y * ib2_ - 1.0;
    v.grad = Vec3(2 * x * ia2_, 2 * y * ib2_, 0);
    v.hess(0, 0) = 2 * ia2_;
    v.hess(1, 1) = 2 * ib2_;
    return v;
  }
  ValueDual eval_dual(const V3D& r, const JS&) const override {
    const JS x = r[0] - JS(cx_.value), y = r[1] - JS(cy_.value);
    ValueDual v = zero_surface_value();
    v.f = x * x * JS(ia2_) + y * y * JS(ib2_) - JS(1.0);
    v.grad = {JS(2.0) * x * JS(ia2_), JS(2.0) * y * JS(ib2_), JS(0.0)};
    v.hess[0] = JS(2 * ia2_);
    v.hess[4] = JS(2 * ib2_);
    return v;
  }
  std::string describe() const override {
    return "((x - " + fmt(cx_) + ")/" + fmt(a_) + ")^2 + ((y - " + fmt(cy_) + ")/" + fmt(b_) + ")^2 - 1";
  }
  std::optional<TaskGeometry> geometry() const override {
    return TaskGeometry{"ellipse", "", {{"cx", cx_}, {"cy", cy_}, {"a", a_}, {"b", b_}}};
  }
  std::optional<SymbolicForm> symbolic(const std::string& P) const override {
    SymbolicForm f = symbolic_rows({"((x(" + P + ") - " + symbolic_number(cx_) + ")/" + symbolic_number(a_) + ")^2 + ((y(" +
                                    P + ") - " + symbolic_number(cy_) + ")/" + symbolic_number(b_) + ")^2 - 1"});
    f.scenario_texts = any_text(a_, b_, cx_, cy_);
    return f;
  }
 private:
  double ia2_, ib2_;
  Number a_, b_, cx_, cy_;  // with the scenario's texts, for the symbolic form
};

class Sphere final : public ImplicitSurface {
 public:
  Sphere(const Number3& c, Number R) : c_(c[0], c[1], c[2]), c_text_(c), R_(std::move(R)) {}
  Value eval(const Vec3& r, double) const override {
    Value v;
    const Vec3 e = r - c_;
    v.f = e.squaredNorm() - R_.value * R_.value;
    v.grad = 2 * e;
    v.hess = 2 * Mat3::Identity();
    return v;
  }
  ValueDual eval_dual(const V3D& r, const JS&) const override {
    ValueDual v = zero_surface_value();
    const V3D e = multibody::sub(r, multibody::lift<JS>(c_));
    v.f = multibody::dot(e, e) - JS(R_.value * R_.value);
    v.grad = multibody::scale(e, JS(2.0));
    v.hess = multibody::scale(multibody::identity3<JS>(), JS(2.0));
    return v;
  }
  std::string describe() const override { return "|r - c|^2 - " + fmt(R_) + "^2"; }
  std::optional<TaskGeometry> geometry() const override {
    return TaskGeometry{"sphere", "", {{"cx", c_.x()}, {"cy", c_.y()}, {"cz", c_.z()}, {"r", R_}}};
  }
  std::optional<SymbolicForm> symbolic(const std::string& P) const override {
    std::string s;
    for (int k = 0; k < 3; ++k)
      s += std::string(k ? " + " : "") + "(" + "xyz"[k] + "(" + P + ") - " + symbolic_number(c_text_[k]) + ")^2";
    SymbolicForm f = symbolic_rows({s + " - " + symbolic_number(R_) + "^2"});
    f.scenario_texts = any_text(c_text_[0], c_text_[1], c_text_[2], R_);
    return f;
  }
 private:
  Vec3 c_;
  Number3 c_text_;  // the centre with the scenario's texts, for the symbolic form
  Number R_;
};

class Plane final : public ImplicitSurface {
 public:
  Plane(const Vec3& n, TimeFunctionPtr h) : n_(n.normalized()), h_(std::move(h)) {}
  Value eval(const Vec3& r, double t) const override {
    const TimeValue h = h_->eval(t);
    Value v;
    v.f = n_.dot(r) - h.f;
    v.grad = n_;
    v.ft = -h.df;
    v.ftt = -h.ddf;
    return v;
  }
  ValueDual eval_dual(const V3D& r, const JS& t) const override {
    const TimeValueDual h = refdyn::eval_dual(*h_, t);
    ValueDual v = zero_surface_value();
    const V3D n = multibody::lift<JS>(n_);
    v.f = multibody::dot(n, r) - h.f;
    v.grad = n;
    v.ft = negated(h.df);
    v.ftt = negated(h.ddf);
    return v;
  }
  bool rheonomic() const override { return true; }
  std::string describe() const override { return "n.r - (" + h_->describe() + ")"; }
  std::optional<SymbolicForm> symbolic(const std::string& P) const override {
    std::optional<SymbolicForm> h = h_->symbolic();
    if (!h) return std::nullopt;
    std::string s;
    for (int k = 0; k < 3; ++k) s += std::string(k ? " + " : "") + symbolic_number(n_[k]) + "*" + "xyz"[k] + "(" + P + ")";
    h->rows[0] = s + " - (" + h->rows[0] + ")";
    return h;
  }
 private:
  Vec3 n_;
  TimeFunctionPtr h_;
};

// ---------------- constraint kinds ----------------
/// before + f(t) + after, with f's parameters; none if f has no symbolic form.
std::optional<SymbolicForm> with_function(const std::string& before, const TimeFunction& f, const std::string& after) {
  std::optional<SymbolicForm> s = f.symbolic();
  if (!s) return std::nullopt;
  s->rows[0] = before + s->rows[0] + after;
  return s;
}

class PointOnSurface final : public Constraint {
 public:
  PointOnSurface(int p, std::string pn, SurfacePtr s) : p_(p), pn_(std::move(pn)), s_(std::move(s)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return s_->rheonomic(); }
  std::vector<int> points() const override { return {p_}; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const PointState& P = in.points[p_];
    const ImplicitSurface::Value f = s_->eval(P.r, in.t);
    phi[0] = f.f;
    phid[0] = f.grad.dot(P.v) + f.ft;
    A.row(0).noalias() = f.grad.transpose().lazyProduct(P.C);
    gamma[0] = f.grad.dot(P.d) + P.v.dot(f.hess * P.v) + 2 * f.grad_t.dot(P.v) + f.ftt;
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    using namespace multibody;
    const PointStateT<JS>& P = in.points[p_];
    const ImplicitSurface::ValueDual f = s_->eval_dual(P.r, in.t);
    phi[0] = f.f;
    phid[0] = dot(f.grad, P.v) + f.ft;
    for (int j = 0; j < in.n; ++j) A[j] = dot(f.grad, P.C[j]);
    gamma[0] = dot(f.grad, P.d) + dot(P.v, mul(f.hess, P.v)) + JS(2.0) * dot(f.grad_t, P.v) + f.ftt;
  }
  std::string describe() const override { return "point " + pn_ + " on surface " + s_->describe() + " = 0"; }
  std::optional<SymbolicForm> symbolic() const override { return s_->symbolic(pn_); }
  std::optional<TaskGeometry> geometry() const override {
    std::optional<TaskGeometry> g = s_->geometry();
    if (g) g->point = pn_;
    return g;
  }
 private:
  int p_;
  std::string pn_;
  SurfacePtr s_;
};

class PointCoordinate final : public Constraint {
 public:
  PointCoordinate(int p, std::string pn, int k, TimeFunctionPtr f) : p_(p), k_(k), pn_(std::move(pn)), f_(std::move(f)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {p_}; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const PointState& P = in.points[p_];
    const TimeValue f = f_->eval(in.t);
    phi[0] = P.r[k_] - f.f;
    phid[0] = P.v[k_] - f.df;
    A.row(0) = P.C.row(k_);
    gamma[0] = P.d[k_] - f.ddf;
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    const PointStateT<JS>& P = in.points[p_];
    const TimeValueDual f = eval_dual(*f_, in.t);
    phi[0] = P.r[k_] - f.f;
    phid[0] = P.v[k_] - f.df;
    for (int j = 0; j < in.n; ++j) A[j] = P.C[j][k_];
    gamma[0] = P.d[k_] - f.ddf;
  }
  std::string describe() const override {
    return std::string("xyz").substr(k_, 1) + "(" + pn_ + ") - (" + f_->describe() + ") = 0";
  }
  std::optional<SymbolicForm> symbolic() const override {
    return with_function(std::string("xyz").substr(k_, 1) + "(" + pn_ + ") - (", *f_, ")");
  }
  const TimeFunction* target() const override { return f_.get(); }
 private:
  int p_, k_;
  std::string pn_;
  TimeFunctionPtr f_;
};

class JointTrajectory final : public Constraint {
 public:
  JointTrajectory(int j, std::string jn, TimeFunctionPtr f) : j_(j), jn_(std::move(jn)), f_(std::move(f)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const TimeValue f = f_->eval(in.t);
    phi[0] = in.q[j_] - f.f;
    phid[0] = in.qd[j_] - f.df;
    A.row(0).setZero();
    A(0, j_) = 1.0;
    gamma[0] = -f.ddf;
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    const TimeValueDual f = eval_dual(*f_, in.t);
    phi[0] = in.q[j_] - f.f;
    phid[0] = in.qd[j_] - f.df;
    std::fill_n(A, in.n, JS(0.0));
    A[j_] = JS(1.0);
    gamma[0] = negated(f.ddf);
  }
  std::string describe() const override { return "q(" + jn_ + ") - (" + f_->describe() + ") = 0"; }
  std::optional<SymbolicForm> symbolic() const override { return with_function("q(" + jn_ + ") - (", *f_, ")"); }
  const TimeFunction* target() const override { return f_.get(); }
 private:
  int j_;
  std::string jn_;
  TimeFunctionPtr f_;
};

class JointCoupling final : public Constraint {
 public:
  JointCoupling(int j, int l, std::string jn, std::string ln, Number ratio, Number offset)
      : j_(j), l_(l), jn_(std::move(jn)), ln_(std::move(ln)), ratio_(std::move(ratio)), offset_(std::move(offset)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return false; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    phi[0] = in.q[j_] - ratio_.value * in.q[l_] - offset_.value;
    phid[0] = in.qd[j_] - ratio_.value * in.qd[l_];
    A.row(0).setZero();
    A(0, j_) = 1.0;
    A(0, l_) = -ratio_.value;
    gamma[0] = 0.0;
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    phi[0] = in.q[j_] - JS(ratio_.value) * in.q[l_] - JS(offset_.value);
    phid[0] = in.qd[j_] - JS(ratio_.value) * in.qd[l_];
    std::fill_n(A, in.n, JS(0.0));
    A[j_] = JS(1.0);
    A[l_] = JS(-ratio_.value);
    gamma[0] = JS(0.0);
  }
  std::string describe() const override {
    return "q(" + jn_ + ") - " + fmt(ratio_) + "*q(" + ln_ + ") - " + fmt(offset_) + " = 0";
  }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f =
        symbolic_rows({"q(" + jn_ + ") - " + symbolic_number(ratio_) + "*q(" + ln_ + ") - " + symbolic_number(offset_)});
    f.scenario_texts = any_text(ratio_, offset_);
    return f;
  }
 private:
  int j_, l_;
  std::string jn_, ln_;
  Number ratio_, offset_;
};

class PointsCoincide final : public Constraint {
 public:
  PointsCoincide(int p1, int p2, std::string n1, std::string n2, std::vector<int> axes)
      : p1_(p1), p2_(p2), n1_(std::move(n1)), n2_(std::move(n2)), axes_(std::move(axes)) {}
  int rows() const override { return static_cast<int>(axes_.size()); }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return false; }
  std::vector<int> points() const override { return {p1_, p2_}; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const PointState& P = in.points[p1_];
    const PointState& Q = in.points[p2_];
    for (size_t i = 0; i < axes_.size(); ++i) {
      const int k = axes_[i];
      phi[i] = P.r[k] - Q.r[k];
      phid[i] = P.v[k] - Q.v[k];
      A.row(i) = P.C.row(k) - Q.C.row(k);
      gamma[i] = P.d[k] - Q.d[k];
    }
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    const PointStateT<JS>& P = in.points[p1_];
    const PointStateT<JS>& Q = in.points[p2_];
    for (size_t i = 0; i < axes_.size(); ++i) {
      const int k = axes_[i];
      phi[i] = P.r[k] - Q.r[k];
      phid[i] = P.v[k] - Q.v[k];
      for (int j = 0; j < in.n; ++j) A[i * in.n + j] = P.C[j][k] - Q.C[j][k];
      gamma[i] = P.d[k] - Q.d[k];
    }
  }
  std::string describe() const override { return "r(" + n1_ + ") - r(" + n2_ + ") = 0"; }
  std::optional<SymbolicForm> symbolic() const override {
    SymbolicForm f;
    for (int k : axes_) {
      const std::string a(1, "xyz"[k]);
      f.rows.push_back(a + "(" + n1_ + ") - " + a + "(" + n2_ + ")");
    }
    return f;
  }
 private:
  int p1_, p2_;
  std::string n1_, n2_;
  std::vector<int> axes_;
};

class KnifeEdge final : public Constraint {
 public:
  KnifeEdge(int p, std::string pn, const Vec3& a) : p_(p), pn_(std::move(pn)), a_(a.normalized()) {}
  int rows() const override { return 1; }
  bool first_order() const override { return true; }
  bool rheonomic() const override { return false; }
  std::vector<int> points() const override { return {p_}; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const PointState& P = in.points[p_];
    const Vec3 n = P.R * a_;
    phi[0] = n.dot(P.v);
    phid[0] = phi[0];
    A.row(0).noalias() = n.transpose().lazyProduct(P.C);
    gamma[0] = P.w.cross(n).dot(P.v) + n.dot(P.d);
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    using namespace multibody;
    const PointStateT<JS>& P = in.points[p_];
    const V3D n = mul(P.R, lift<JS>(a_));
    phi[0] = dot(n, P.v);
    phid[0] = phi[0];
    for (int j = 0; j < in.n; ++j) A[j] = dot(n, P.C[j]);
    gamma[0] = dot(cross(P.w, n), P.v) + dot(n, P.d);
  }
  std::string describe() const override { return "no lateral slip at " + pn_; }
  std::optional<SymbolicForm> symbolic() const override {
    // (R a)·v_P
    std::string s;
    for (int r = 0; r < 3; ++r) {
      std::string nr;
      for (int c = 0; c < 3; ++c)
        if (a_[c] != 0.0)
          nr += std::string(nr.empty() ? "" : " + ") + "R" + std::to_string(r + 1) + std::to_string(c + 1) + "(" + pn_ +
                ")*" + symbolic_number(a_[c]);
      if (!nr.empty()) s += std::string(s.empty() ? "" : " + ") + "(" + nr + ")*v" + "xyz"[r] + "(" + pn_ + ")";
    }
    return symbolic_rows({s.empty() ? "0" : s});
  }
 private:
  int p_;
  std::string pn_;
  Vec3 a_;
};

class PointSpeed final : public Constraint {
 public:
  PointSpeed(int p, std::string pn, const Vec3& u, TimeFunctionPtr s) : p_(p), pn_(std::move(pn)), u_(u.normalized()), s_(std::move(s)) {}
  int rows() const override { return 1; }
  bool first_order() const override { return true; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {p_}; }
  void evaluate(const ConstraintInput& in, Eigen::Ref<Eigen::VectorXd> phi, Eigen::Ref<Eigen::VectorXd> phid,
                Eigen::Ref<Eigen::MatrixXd> A, Eigen::Ref<Eigen::VectorXd> gamma) const override {
    const PointState& P = in.points[p_];
    const TimeValue s = s_->eval(in.t);
    phi[0] = u_.dot(P.v) - s.f;
    phid[0] = phi[0];
    A.row(0).noalias() = u_.transpose().lazyProduct(P.C);
    gamma[0] = u_.dot(P.d) - s.df;
  }
  void evaluate_dual(const ConstraintInputDual& in, JS* phi, JS* phid, JS* A, JS* gamma) const override {
    using namespace multibody;
    const PointStateT<JS>& P = in.points[p_];
    const TimeValueDual s = refdyn::eval_dual(*s_, in.t);
    const V3D u = lift<JS>(u_);
    phi[0] = dot(u, P.v) - s.f;
    phid[0] = phi[0];
    for (int j = 0; j < in.n; ++j) A[j] = dot(u, P.C[j]);
    gamma[0] = dot(u, P.d) - s.df;
  }
  std::string describe() const override { return "u.v(" + pn_ + ") - (" + s_->describe() + ") = 0"; }
  std::optional<SymbolicForm> symbolic() const override {
    std::string s;
    for (int k = 0; k < 3; ++k)
      if (u_[k] != 0.0) s += std::string(s.empty() ? "" : " + ") + symbolic_number(u_[k]) + "*v" + "xyz"[k] + "(" + pn_ + ")";
    return with_function((s.empty() ? "0" : s) + " - (", *s_, ")");
  }
  const TimeFunction* target() const override { return s_.get(); }
 private:
  int p_;
  std::string pn_;
  Vec3 u_;
  TimeFunctionPtr s_;
};

template <typename T>
std::shared_ptr<T> named(std::shared_ptr<T> c, std::string name, ConstraintOrigin o) {
  c->name = std::move(name);
  c->origin = o;
  return c;
}

void need_axis(int axis, const char* what) {
  if (axis < 0 || axis > 2) throw Error(expected_got(what, "0 (x), 1 (y) or 2 (z)", std::to_string(axis)));
}
void need_vec(const Vec3& v, const std::string& what) {
  if (!v.allFinite() || v.norm() < 1e-12) throw Error(expected_got(what, "a finite non-zero vector", "zero or NaN"));
}

}  // namespace

SurfacePtr elliptic_cylinder(Number a, Number b, Number cx, Number cy) {
  if (!(std::isfinite(a.value) && a > 0) || !(std::isfinite(b.value) && b > 0))
    throw Error(expected_got("ellipse half-axes", "finite values > 0", fmt(a) + ", " + fmt(b)));
  if (!std::isfinite(cx.value) || !std::isfinite(cy.value)) throw Error("ellipse centre must be finite");
  return std::make_shared<EllipticCylinder>(std::move(a), std::move(b), std::move(cx), std::move(cy));
}
SurfacePtr sphere(const Number3& c, Number R) {
  if (!Vec3(c[0], c[1], c[2]).allFinite() || !(std::isfinite(R.value) && R > 0))
    throw Error(expected_got("sphere", "a finite centre and radius > 0", fmt(R)));
  return std::make_shared<Sphere>(c, std::move(R));
}
SurfacePtr sphere(const Vec3& c, double R) { return sphere(Number3{c.x(), c.y(), c.z()}, R); }
SurfacePtr plane(const Vec3& n, TimeFunctionPtr h) {
  need_vec(n, "plane normal");
  if (!h) throw Error("plane: expected an offset function, got none");
  return std::make_shared<Plane>(n, std::move(h));
}

NewConstraint point_on_surface(const Model& m, const std::string& point, SurfacePtr s, ConstraintOrigin o) {
  if (!s) throw Error("point_on_surface: expected a surface, got none");
  return named(std::make_shared<PointOnSurface>(m.point_index(point), point, std::move(s)), point + "_on_surface", o);
}
NewConstraint point_coordinate(const Model& m, const std::string& point, int axis, TimeFunctionPtr f,
                               ConstraintOrigin o) {
  need_axis(axis, "point_coordinate axis");
  if (!f) throw Error("point_coordinate: expected a time function, got none");
  return named(std::make_shared<PointCoordinate>(m.point_index(point), point, axis, std::move(f)),
               std::string("xyz").substr(axis, 1) + "_" + point, o);
}
NewConstraint joint_trajectory(const Model& m, const std::string& joint, TimeFunctionPtr f, ConstraintOrigin o) {
  if (!f) throw Error("joint_trajectory: expected a time function, got none");
  return named(std::make_shared<JointTrajectory>(m.joint_index(joint), joint, std::move(f)), "q_" + joint, o);
}
NewConstraint joint_coupling(const Model& m, const std::string& joint, const std::string& leader, Number ratio,
                             Number offset, ConstraintOrigin o) {
  if (!std::isfinite(ratio.value) || !std::isfinite(offset.value))
    throw Error(expected_got("joint_coupling ratio and offset", "finite numbers", fmt(ratio) + ", " + fmt(offset)));
  const int j = m.joint_index(joint), l = m.joint_index(leader);
  if (j == l) throw Error("joint_coupling: joint '" + joint + "' cannot be coupled to itself (hint: name another leader)");
  return named(std::make_shared<JointCoupling>(j, l, joint, leader, ratio, offset), joint + "_from_" + leader, o);
}
NewConstraint points_coincide(const Model& m, const std::string& p1, const std::string& p2, std::vector<int> axes,
                              ConstraintOrigin o) {
  if (axes.empty()) throw Error("points_coincide: expected at least one axis, got none");
  for (int a : axes) need_axis(a, "points_coincide axis");
  const int i1 = m.point_index(p1), i2 = m.point_index(p2);
  if (i1 == i2) throw Error("points_coincide: the two points are the same ('" + p1 + "')");
  return named(std::make_shared<PointsCoincide>(i1, i2, p1, p2, std::move(axes)), p1 + "_at_" + p2, o);
}
NewConstraint knife_edge(const Model& m, const std::string& point, const Vec3& a, ConstraintOrigin o) {
  need_vec(a, "knife_edge lateral axis");
  return named(std::make_shared<KnifeEdge>(m.point_index(point), point, a), "no_slip_" + point, o);
}
NewConstraint point_speed(const Model& m, const std::string& point, const Vec3& u, TimeFunctionPtr s,
                          ConstraintOrigin o) {
  need_vec(u, "point_speed direction");
  if (!s) throw Error("point_speed: expected a speed function, got none");
  return named(std::make_shared<PointSpeed>(m.point_index(point), point, u, std::move(s)), "speed_" + point, o);
}

// ---------------- set and evaluation ----------------
void ConstraintSet::add(ConstraintPtr c) {
  if (!c) throw Error("ConstraintSet::add: expected a constraint, got none");
  for (const auto& e : constraints_)
    if (e->name == c->name)
      throw Error("constraint '" + c->name + "' is defined twice (hint: give each constraint its own name)");
  offsets_.push_back(rows_);
  rows_ += c->rows();
  for (int p : c->points())
    if (std::find(points_.begin(), points_.end(), p) == points_.end()) points_.push_back(p);
  constraints_.push_back(std::move(c));
}

int ConstraintSet::row_owner(int row) const {
  int k = 0;
  while (k + 1 < size() && offsets_[k + 1] <= row) ++k;
  return k;
}

std::string ConstraintSet::row_name(int row) const {
  const int k = row_owner(row);
  const auto& c = constraints_[k];
  return c->rows() == 1 ? c->name : c->name + "[" + std::to_string(row - offsets_[k]) + "]";
}

ConstraintEval::ConstraintEval(const Model& model, const ConstraintSet& set)
    : phi(Eigen::VectorXd::Zero(set.rows())), phid(Eigen::VectorXd::Zero(set.rows())),
      gamma(Eigen::VectorXd::Zero(set.rows())), A(Eigen::MatrixXd::Zero(set.rows(), model.nv)),
      points(model.point_name.size()) {
  int most = 0;
  for (const auto& c : set.constraints()) most = std::max(most, c->scratch_size());
  scratch.assign(static_cast<size_t>(most), 0.0);
  for (auto& p : points) {
    p.C = Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nv);
    p.Jw = Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, model.nv);
  }
}

namespace {
/// Point states from body motions already in data.v, data.a (and data.oMi). `a_offset` is
/// subtracted from every world-frame drift: the base acceleration data.a was propagated with.
void point_states_from_body_motion(const Model& model, const Data& data, const std::vector<int>& pts,
                                   const Vec3& a_offset, std::vector<PointState>& out) {
  for (int k : pts) {
    PointState& P = out[k];
    const int b = model.point_body[k];
    if (b < 0) {
      P.r = model.point_position[k];
      P.v.setZero();
      P.d.setZero();
      P.w.setZero();
      P.wd.setZero();
      P.R.setIdentity();
      P.C.setZero();
      P.Jw.setZero();
      continue;
    }
    const PointDrift pd = kinematics_detail::point_drift_on_body(data, b, model.point_position[k]);
    P.r = data.oMi[b].act_point(model.point_position[k]);
    P.R = data.oMi[b].R;
    P.v = pd.velocity;
    P.d = pd.drift - a_offset;
    P.w = pd.omega;
    P.wd = pd.omega_drift;
    kinematics_detail::point_jacobian_at(model, data, b, P.r, P.C, P.Jw);
  }
}

void compose_world_placements(const Model& model, Data& data) {
  for (int i = 0; i < model.nq; ++i) {
    const int p = model.parent[i];
    data.oMi[i] = p < 0 ? data.liMi[i] : data.oMi[p] * data.liMi[i];
  }
}
}  // namespace

void compute_point_states(const Model& model, Data& data, const std::vector<int>& pts, const Eigen::VectorXd& qd,
                          std::vector<PointState>& out) {
  // Body velocities and drift accelerations (q̈ = 0), body frames.
  for (int i = 0; i < model.nq; ++i) kinematics_detail::propagate_velocity_drift(model, data, i, qd);
  point_states_from_body_motion(model, data, pts, Vec3::Zero(), out);
}

namespace {
void evaluate_rows(const ConstraintSet& set, ConstraintEval& ev, double t, const Eigen::VectorXd& q,
                   const Eigen::VectorXd& qd) {
  const ConstraintInput in{t, q, qd, ev.points, ev.scratch.data()};
  for (int k = 0; k < set.size(); ++k) {
    const auto& c = set.constraints()[k];
    const int r = set.row_offset(k), m = c->rows();
    c->evaluate(in, ev.phi.segment(r, m), ev.phid.segment(r, m), ev.A.middleRows(r, m), ev.gamma.segment(r, m));
  }
}
}  // namespace

void evaluate_constraints(const Model& model, Data& data, const ConstraintSet& set, ConstraintEval& ev, double t,
                          const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  check_data(model, data);
  if (q.size() != model.nq) model.check_q(q);
  if (qd.size() != model.nv) check_vector("qd", qd, model.nv);
  if (ev.phi.size() != set.rows() || ev.A.cols() != model.nv || ev.points.size() != model.point_name.size())
    throw Error("evaluate_constraints: the ConstraintEval was built for another model or constraint set (hint: "
                "ConstraintEval ev(model, set) with the same model and set)");
  unchecked::forward_kinematics(model, data, q);
  compute_point_states(model, data, set.points(), qd, ev.points);
  evaluate_rows(set, ev, t, q, qd);
}

void evaluate_constraints_after_bias_forces(const Model& model, Data& data, const ConstraintSet& set,
                                            ConstraintEval& ev, double t, const Eigen::VectorXd& q,
                                            const Eigen::VectorXd& qd) {
  compose_world_placements(model, data);
  // RNEA with q̈ = 0 left the drift accelerations plus the base acceleration −g, carried into
  // every body as a pure translation: subtract it in the world frame.
  point_states_from_body_motion(model, data, set.points(), -model.gravity, ev.points);
  evaluate_rows(set, ev, t, q, qd);
}

// ---------------- dual-number evaluation ----------------
ConstraintEvalDual::ConstraintEvalDual(const Model& model, const ConstraintSet& set)
    : model_id(model.id), m(set.rows()), n(model.nv), phi(set.rows()), phid(set.rows()), gamma(set.rows()),
      A(static_cast<size_t>(set.rows()) * model.nv), points(model.point_name.size()),
      bodies(multibody::bodies_from_model<JS>(model)), q(model.nv) {
  int most = 0;
  for (const auto& c : set.constraints()) most = std::max(most, c->scratch_size_dual());
  scratch.assign(static_cast<size_t>(most), JS(0.0));
  for (auto& p : points) {
    p.r = p.v = p.d = p.w = p.wd = multibody::zero3<JS>();
    p.R = multibody::identity3<JS>();
    p.C.assign(model.nv, multibody::zero3<JS>());
    p.Jw.assign(model.nv, multibody::zero3<JS>());
  }
  // size the kinematics once (no allocation in the evaluations)
  multibody::forward_poses(bodies, q, poses);
  multibody::forward_motion(bodies, poses, q.data(), static_cast<const JS*>(nullptr), multibody::zero3<JS>(), true,
                            motion);
}

void evaluate_constraints_dual(const Model& model, const ConstraintSet& set, ConstraintEvalDual& ev, const JS& t,
                               const JS* q, const JS* qd) {
  using namespace multibody;
  if (ev.model_id != model.id || ev.m != set.rows() || ev.n != model.nv ||
      ev.points.size() != model.point_name.size())
    throw Error("evaluate_constraints_dual: the ConstraintEvalDual was built for another model or constraint set "
                "(hint: ConstraintEvalDual ev(model, set) with the same model and set)");
  if (!q || !qd) throw Error("evaluate_constraints_dual: expected q and qd (n dual numbers each), got a null pointer");
  const int n = model.nv;
  std::copy(q, q + n, ev.q.begin());
  forward_poses(ev.bodies, ev.q, ev.poses);
  // velocities and drift accelerations (q̈ = 0), base at rest (kinematics, not gravity)
  forward_motion(ev.bodies, ev.poses, qd, static_cast<const JS*>(nullptr), zero3<JS>(), true, ev.motion);
  for (int k : set.points()) {
    PointStateT<JS>& P = ev.points[k];
    const int b = model.point_body[k];
    std::fill(P.C.begin(), P.C.end(), zero3<JS>());
    std::fill(P.Jw.begin(), P.Jw.end(), zero3<JS>());
    if (b < 0) {
      P.r = ev.bodies.points[k].position;
      P.v = P.d = P.w = P.wd = zero3<JS>();
      P.R = identity3<JS>();
      continue;
    }
    const PointKinematics<JS> pk = point_kinematics(ev.bodies.points[k], ev.poses, ev.motion);
    P.r = pk.r;
    P.v = pk.v;
    P.d = pk.a;
    P.R = ev.poses.R[b];
    P.w = mul(P.R, ev.motion.w[b]);
    P.wd = mul(P.R, ev.motion.wd[b]);
    for (int j : model.support[b]) {
      P.C[j] = point_jacobian_column(ev.bodies, ev.poses, j, P.r);
      if (model.joint_type[j] == JointType::Revolute) P.Jw[j] = mul(ev.poses.R[j], ev.bodies.bodies[j].axis);
    }
  }
  std::fill(ev.A.begin(), ev.A.end(), JS(0.0));
  const ConstraintInputDual in{t, n, q, qd, ev.points, ev.scratch.data()};
  for (int k = 0; k < set.size(); ++k) {
    const auto& c = set.constraints()[k];
    const int r = set.row_offset(k);
    c->evaluate_dual(in, ev.phi.data() + r, ev.phid.data() + r, ev.A.data() + static_cast<size_t>(r) * n,
                     ev.gamma.data() + r);
  }
}

}  // namespace refdyn
