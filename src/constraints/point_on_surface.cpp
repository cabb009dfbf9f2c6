// point_on_surface: a point on an implicit curve or surface, f(r_P, t) = 0 (surfaces.cpp):
//   Φ = f,  Φ̇ = f_r·v + f_t,  A = f_rᵀ C,  γ = f_r·d + vᵀ f_rr v + 2 f_rt·v + f_tt.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class PointOnSurface final : public ConstraintLaw<PointOnSurface> {
 public:
  PointOnSurface(int p, std::string pn, SurfacePtr s) : p_(p), pn_(std::move(pn)), s_(std::move(s)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    using namespace law_ops;
    const auto& P = in.points[p_];
    const auto f = surface_value(*s_, P.r, in.t);
    out.phi[0] = f.f;
    out.phid[0] = dot(f.grad, P.v) + f.ft;
    out.A_dot(0, f.grad, P.C);
    out.gamma[0] = dot(f.grad, P.d) + dot(P.v, mul(f.hess, P.v)) + S(2.0) * dot(f.grad_t, P.v) + f.ftt;
  }
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return s_->rheonomic(); }
  bool exact_derivatives() const override { return s_->exact_derivatives(); }
  std::vector<int> points() const override { return {p_}; }
  std::string describe() const override { return "point " + pn_ + " on surface " + s_->describe() + " = 0"; }
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

}  // namespace

NewConstraint point_on_surface(const Model& m, const std::string& point, SurfacePtr s, ConstraintOrigin o) {
  if (!s) throw Error("point_on_surface: expected a surface, got none");
  return constraint_detail::named(std::make_shared<PointOnSurface>(m.point_index(point), point, std::move(s)),
                                  point + "_on_surface", o);
}

}  // namespace refdyn
