// The distance between two points follows a function of time: |r_A − r_B| − d(t) = 0.
// A kind added as one file plus one line in kinds.def (the README's "adding a kind").
//
// With Δ = r_A − r_B, ρ = |Δ|, u = Δ/ρ and Δ̇ = v_A − v_B:
//   Φ = ρ − d,   Φ̇ = u·Δ̇ − ḋ,   A = uᵀ (C_A − C_B),
//   Φ̈ = A q̈ + γ,   γ = u·(d_A − d_B) + (|Δ̇|² − (u·Δ̇)²)/ρ − d̈
// (d_P: the drift acceleration of P, the part of its acceleration that does not depend on q̈),
// written once as law<S> (ConstraintLaw, constraints/law.hpp): evaluate() and evaluate_dual()
// are its instantiations.
// The constraint is undefined when the points coincide (ρ = 0): evaluation stops there.
#include "kinds.hpp"

#include "refdyn/constraints/law.hpp"
#include "refdyn/reference/reference_dynamics.hpp"
#include "refdyn/common/text.hpp"

namespace refdyn::kinds {

namespace {

class Distance final : public ConstraintLaw<Distance> {
 public:
  Distance(const Model& m, const std::string& a, const std::string& b, TimeFunctionPtr d)
      : a_(m.point_index(a)), b_(m.point_index(b)), an_(a), bn_(b), d_(std::move(d)) {
    if (a_ == b_) throw Error("distance: expected two different points, got '" + a + "' twice");
  }
  template <class S>
  void law(const LawInput<S>& in, LawRows<S>& out) const {
    using namespace law_ops;
    const auto& P = in.points[a_];
    const auto& Q = in.points[b_];
    const auto delta = sub(P.r, Q.r), delta_dot = sub(P.v, Q.v);
    const S rho = norm(delta);
    if (not_above(rho, 1e-12)) {
      const double t = value_of(in.t);
      throw NumericalFailure(t, "at t = " + fmt(t) + " s the points '" + an_ + "' and '" + bn_ +
                                    "' of distance constraint '" + name + "' coincide: the distance has no direction there");
    }
    const auto u = div(delta, rho);
    const auto d = time_value(*d_, in.t);
    const S ud = dot(u, delta_dot);
    out.phi[0] = rho - d.f;
    out.phid[0] = ud - d.df;
    out.A_dot_diff(0, u, P.C, Q.C);
    out.gamma[0] = dot(u, sub(P.d, Q.d)) + (squared_norm(delta_dot) - ud * ud) / rho - d.ddf;
  }
  int rows() const override { return 1; }
  bool first_order() const override { return false; }
  bool rheonomic() const override { return true; }
  std::vector<int> points() const override { return {a_, b_}; }
  const TimeFunction* target() const override { return d_.get(); }
  std::string describe() const override {
    return "|r(" + an_ + ") - r(" + bn_ + ")| - (" + d_->describe() + ") = 0";
  }

 private:
  int a_, b_;
  std::string an_, bn_;
  TimeFunctionPtr d_;
};

}  // namespace

ConstraintKind constraint_distance() {
  ConstraintKind k;
  k.name = "distance";
  k.doc = "the distance between two points follows a function of time: |r_A − r_B| − d(t) = 0 (a rod, a cable "
          "length, a telescoping task)";
  k.keys = {{"points", "[A, B]", true, "", "the two points"},
            {"length", "function of t", true, "", "d(t) [m], > 0"},
            {"record", "name", false, "", "record d(t) in plan.csv under this column name"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) -> NewConstraint {
    const SpecValue& ps = a.reader.need(a.entry.fields, "points", a.entry.key);
    if (!ps.is_list() || ps.size() != 2) a.fail("points", "expected two point names [A, B]");
    const std::string p0 = a.reader.point(ps[0], a.key("points"), a.model);
    const std::string p1 = a.reader.point(ps[1], a.key("points"), a.model);
    auto c = std::make_shared<Distance>(a.model, p0, p1, a.function("length"));
    c->origin = origin;
    return c;
  };
  return k;
}

}  // namespace refdyn::kinds
