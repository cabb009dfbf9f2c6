// point_coordinate: a world coordinate of a point follows a function of time,
//   Φ = r_k − f(t),  Φ̇ = v_k − f',  A = C(k, :),  γ = d_k − f''.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class PointCoordinate final : public ConstraintLaw<PointCoordinate> {
 public:
  PointCoordinate(int p, std::string pn, int k, TimeFunctionPtr f) : p_(p), k_(k), pn_(std::move(pn)), f_(std::move(f)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    const auto& P = in.points[p_];
    const auto f = time_value(*f_, in.t);
    out.phi[0] = P.r[k_] - f.f;
    out.phid[0] = P.v[k_] - f.df;
    out.A_axis(0, P.C, k_);
    out.gamma[0] = P.d[k_] - f.ddf;
  }
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {p_}; }
  std::string describe() const override {
    return std::string("xyz").substr(k_, 1) + "(" + pn_ + ") - (" + f_->describe() + ") = 0";
  }
  const TimeFunction* target() const override { return f_.get(); }
 private:
  int p_, k_;
  std::string pn_;
  TimeFunctionPtr f_;
};

}  // namespace

NewConstraint point_coordinate(const Model& m, const std::string& point, int axis, TimeFunctionPtr f,
                               ConstraintOrigin o) {
  constraint_detail::need_axis(axis, "point_coordinate axis");
  if (!f) throw Error("point_coordinate: expected a time function, got none");
  return constraint_detail::named(std::make_shared<PointCoordinate>(m.point_index(point), point, axis, std::move(f)),
                                  std::string("xyz").substr(axis, 1) + "_" + point, o);
}

}  // namespace refdyn
