#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_expression() {
  ConstraintKind k;
  k.name = "expression";
  k.doc = "a constraint written as an expression over x(P), y(P), z(P), q(joint), t and the parameters "
          "(first order: also vx(P), vy(P), vz(P), qd(joint); acceleration: also ax(P), ay(P), az(P), "
          "qdd(joint), linear in them); exact derivatives (GiNaC). Written as `expression: TEXT` (the "
          "`kind:` key may be omitted).";
  k.keys = {{"expression", "text", true, "", "the constraint function, = 0"},
            {"order", "position | velocity | acceleration", false, "position",
             "holonomic Φ(q, t) = 0, first-order c(q, q̇, t) = 0, or acceleration-level B(t, q, q̇) q̈ + s = 0 "
             "(programmed, p = 2; docs/higher_order.md)"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    ConstraintOrder order = ConstraintOrder::Position;
    if (a.has("order")) {
      const SpecValue& v = a.value("order");
      if (v.is_scalar() && v.text == "jerk")
        a.fail("order",
               "order: jerk (programmed constraints of order p = 3) is not implemented; the supported orders "
               "are position, velocity and acceleration (see docs/higher_order.md)");
      const std::string o = a.reader.choice(v, a.key("order"), {"position", "velocity", "acceleration"});
      order = o == "velocity" ? ConstraintOrder::Velocity
              : o == "acceleration" ? ConstraintOrder::Acceleration : ConstraintOrder::Position;
    }
    if (order == ConstraintOrder::Acceleration && origin == ConstraintOrigin::Material)
      a.fail("origin", "an acceleration-level constraint (order: acceleration) is programmed: material constraints "
                       "have order position or velocity (the paper's eq. 2.1, p = 0, 1)");
    return expression_constraint(a.model, a.entry.name, a.text("expression"), order, a.reader.params, origin);
  };
  return k;
}

}  // namespace refdyn::kinds
