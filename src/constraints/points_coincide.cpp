// points_coincide: two points coincide (loop closure) on the selected world axes k,
//   Φ = r1_k − r2_k,  Φ̇ = v1_k − v2_k,  A = C1(k, :) − C2(k, :),  γ = d1_k − d2_k.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class PointsCoincide final : public ConstraintLaw<PointsCoincide> {
 public:
  PointsCoincide(int p1, int p2, std::string n1, std::string n2, std::vector<int> axes)
      : p1_(p1), p2_(p2), n1_(std::move(n1)), n2_(std::move(n2)), axes_(std::move(axes)) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    const auto& P = in.points[p1_];
    const auto& Q = in.points[p2_];
    for (size_t i = 0; i < axes_.size(); ++i) {
      const int k = axes_[i];
      out.phi[i] = P.r[k] - Q.r[k];
      out.phid[i] = P.v[k] - Q.v[k];
      out.A_axis_diff(static_cast<int>(i), P.C, Q.C, k);
      out.gamma[i] = P.d[k] - Q.d[k];
    }
  }
  int rows() const override { return static_cast<int>(axes_.size()); }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return false; }
  std::vector<int> points() const override { return {p1_, p2_}; }
  std::string describe() const override { return "r(" + n1_ + ") - r(" + n2_ + ") = 0"; }
 private:
  int p1_, p2_;
  std::string n1_, n2_;
  std::vector<int> axes_;
};

}  // namespace

NewConstraint points_coincide(const Model& m, const std::string& p1, const std::string& p2, std::vector<int> axes,
                              ConstraintOrigin o) {
  if (axes.empty()) throw Error("points_coincide: expected at least one axis, got none");
  for (int a : axes) constraint_detail::need_axis(a, "points_coincide axis");
  const int i1 = m.point_index(p1), i2 = m.point_index(p2);
  if (i1 == i2) throw Error("points_coincide: the two points are the same ('" + p1 + "')");
  return constraint_detail::named(std::make_shared<PointsCoincide>(i1, i2, p1, p2, std::move(axes)), p1 + "_at_" + p2,
                                  o);
}

}  // namespace refdyn
