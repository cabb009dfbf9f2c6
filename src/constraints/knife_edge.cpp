// knife_edge: no lateral slip of a wheel or knife edge at point P (nonholonomic, first order):
// with n = R_b a (a fixed in the body carrying P),
//   c = n·v,  A = nᵀ C,  γ = (ω × n)·v + n·d.
#include "kind_support.hpp"

namespace refdyn {

namespace {

class KnifeEdge final : public ConstraintLaw<KnifeEdge> {
 public:
  KnifeEdge(int p, std::string pn, const Vec3& a) : p_(p), pn_(std::move(pn)), a_(a.normalized()) {}
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    using namespace law_ops;
    const auto& P = in.points[p_];
    const auto n = mul(P.R, constant3<S>(a_));
    out.phi[0] = dot(n, P.v);
    out.phid[0] = out.phi[0];
    out.A_dot(0, n, P.C);
    out.gamma[0] = dot(cross(P.w, n), P.v) + dot(n, P.d);
  }
  int rows() const override { return 1; }
  bool first_order() const override { return true; }
  bool rheonomic() const override { return false; }
  std::vector<int> points() const override { return {p_}; }
  std::string describe() const override { return "no lateral slip at " + pn_; }
 private:
  int p_;
  std::string pn_;
  Vec3 a_;
};

}  // namespace

NewConstraint knife_edge(const Model& m, const std::string& point, const Vec3& a, ConstraintOrigin o) {
  constraint_detail::need_vec(a, "knife_edge lateral axis");
  return constraint_detail::named(std::make_shared<KnifeEdge>(m.point_index(point), point, a), "no_slip_" + point, o);
}

}  // namespace refdyn
