// point_speed: the speed of a point along a fixed world direction u follows s(t) (first order),
//   c = u·v − s(t),  A = uᵀ C,  γ = u·d − s'.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class PointSpeed final : public ConstraintLaw<PointSpeed> {
 public:
  PointSpeed(int p, std::string pn, const Vec3& u, TimeFunctionPtr s)
      : p_(p), pn_(std::move(pn)), u_(u.normalized()), s_(std::move(s)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    using namespace law_ops;
    const auto& P = in.points[p_];
    const auto s = time_value(*s_, in.t);
    const auto& u = constant3<S>(u_);
    out.phi[0] = dot(u, P.v) - s.f;
    out.phid[0] = out.phi[0];
    out.A_dot(0, u, P.C);
    out.gamma[0] = dot(u, P.d) - s.df;
  }
  int rows() const override { return 1; }
  bool first_order() const override { return true; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {p_}; }
  std::string describe() const override { return "u.v(" + pn_ + ") - (" + s_->describe() + ") = 0"; }
  const TimeFunction* target() const override { return s_.get(); }
 private:
  int p_;
  std::string pn_;
  Vec3 u_;
  TimeFunctionPtr s_;
};

}  // namespace

NewConstraint point_speed(const Model& m, const std::string& point, const Vec3& u, TimeFunctionPtr s,
                          ConstraintOrigin o) {
  constraint_detail::need_vec(u, "point_speed direction");
  if (!s) throw Error("point_speed: expected a speed function, got none");
  return constraint_detail::named(std::make_shared<PointSpeed>(m.point_index(point), point, u, std::move(s)),
                                  "speed_" + point, o);
}

}  // namespace refdyn
