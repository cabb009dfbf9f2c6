// Implicit surfaces f(r, t) = 0 for point_on_surface (point_on_surface.cpp): the elliptic
// cylinder (the paper's ellipse), the sphere and the moving plane, each written once as
// law<S> (SurfaceLaw, law.hpp).
#include "kind_support.hpp"

#include <cmath>

namespace refdyn {

using JS = JacobianScalar;

ImplicitSurface::ValueDual ImplicitSurface::eval_dual(const multibody::Vec3T<JS>&, const JS&) const {
  throw Error("surface " + describe() +
              " has no exact derivatives: its kind does not implement eval_dual (hint: an implicit integrator's "
              "exact Jacobian needs it; use an explicit integrator)");
}

namespace {

/// ((x − cx)/a)² + ((y − cy)/b)² − 1 with 1/a², 1/b² folded once (the paper's arithmetic).
class EllipticCylinder final : public SurfaceLaw<EllipticCylinder> {
 public:
  EllipticCylinder(Number a, Number b, Number cx, Number cy)
      : ia2_(inverse_square(a)), ib2_(inverse_square(b)), a_(std::move(a)), b_(std::move(b)), cx_(std::move(cx)),
        cy_(std::move(cy)) {}
  template <class S>
  void law(const LawVec3<S>& r, const S&, typename LawTypes<S>::SurfaceValue& v) const {
    using namespace law_ops;
    const S x = r[0] - S(param<S>(cx_)), y = r[1] - S(param<S>(cy_));
    v.f = x * x * S(param<S>(ia2_)) + y * y * S(param<S>(ib2_)) - S(1.0);
    v.grad = vec3(S(2.0) * x * S(ia2_), S(2.0) * y * S(ib2_), S(0.0));
    set_entry(v.hess, 0, 0, S(2 * ia2_));
    set_entry(v.hess, 1, 1, S(2 * ib2_));
  }
  std::string describe() const override {
    return "((x - " + fmt(cx_) + ")/" + fmt(a_) + ")^2 + ((y - " + fmt(cy_) + ")/" + fmt(b_) + ")^2 - 1";
  }
  std::optional<TaskGeometry> geometry() const override {
    return TaskGeometry{"ellipse", "", {{"cx", cx_}, {"cy", cy_}, {"a", a_}, {"b", b_}}};
  }

 private:
  /// 1/a², folded once (the paper's arithmetic), with the text 1/(a)^2 where a has one.
  static Number inverse_square(const Number& a) {
    return Number(1 / (a * a), a.text.empty() ? "" : "1/" + symbolic_number(a) + "^2");
  }
  Number ia2_, ib2_;
  Number a_, b_, cx_, cy_;  // with the scenario's texts, for the symbolic form
};

/// |r − c|² − R²
class Sphere final : public SurfaceLaw<Sphere> {
 public:
  Sphere(const Number3& c, Number R) : c_(c[0], c[1], c[2]), c_text_(c), R_(std::move(R)) {}
  template <class S>
  void law(const LawVec3<S>& r, const S&, typename LawTypes<S>::SurfaceValue& v) const {
    using namespace law_ops;
    const auto e = sub(r, constant3<S>(c_, c_text_));
    v.f = squared_norm(e) - S(param<S>(R_) * param<S>(R_));
    v.grad = scale(e, S(2.0));
    v.hess = scaled_identity(S(2.0));
  }
  std::string describe() const override { return "|r - c|^2 - " + fmt(R_) + "^2"; }
  std::optional<TaskGeometry> geometry() const override {
    return TaskGeometry{"sphere", "", {{"cx", c_.x()}, {"cy", c_.y()}, {"cz", c_.z()}, {"r", R_}}};
  }
 private:
  Vec3 c_;
  Number3 c_text_;  // the centre with the scenario's texts, for the symbolic form
  Number R_;
};

/// n·r − h(t), n normalised.
class Plane final : public SurfaceLaw<Plane> {
 public:
  Plane(const Vec3& n, TimeFunctionPtr h) : n_(n.normalized()), h_(std::move(h)) {}
  template <class S>
  void law(const LawVec3<S>& r, const S& t, typename LawTypes<S>::SurfaceValue& v) const {
    using namespace law_ops;
    const auto h = time_value(*h_, t);
    const auto& n = constant3<S>(n_);
    v.f = dot(n, r) - h.f;
    v.grad = n;
    v.ft = neg(h.df);
    v.ftt = neg(h.ddf);
  }
  bool rheonomic() const override { return true; }
  std::string describe() const override { return "n.r - (" + h_->describe() + ")"; }
 private:
  Vec3 n_;
  TimeFunctionPtr h_;
};

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
  constraint_detail::need_vec(n, "plane normal");
  if (!h) throw Error("plane: expected an offset function, got none");
  return std::make_shared<Plane>(n, std::move(h));
}

}  // namespace refdyn
