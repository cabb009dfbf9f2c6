#include "kinds.hpp"

#include "refdyn/reference/jerk.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_expression() {
  ConstraintKind k;
  k.name = "expression";
  k.doc = "a constraint written as an expression over x(P), y(P), z(P), q(joint), t and the parameters "
          "(first order: also vx(P), vy(P), vz(P), qd(joint); acceleration: also ax(P), ay(P), az(P), "
          "qdd(joint), linear in them; jerk: also jx(P), jy(P), jz(P), qddd(joint), linear in them with coefficients free of accelerations and jerks); exact derivatives (GiNaC). Written as `expression: TEXT` (the "
          "`kind:` key may be omitted).";
  k.keys = {{"expression", "text", true, "", "the constraint function, = 0"},
            {"order", "position | velocity | acceleration | jerk", false, "position",
             "holonomic Φ(q, t) = 0, first-order c(q, q̇, t) = 0, acceleration-level B(t, q, q̇) q̈ + s = 0 "
             "(programmed, p = 2) or jerk-level B(t, q, q̇) q⃛ + s = 0 (programmed, p = 3, only jerk rows and no "
             "force elements with states in the problem); docs/higher_order.md"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    ConstraintOrder order = ConstraintOrder::Position;
    if (a.has("order")) {
      const SpecValue& v = a.value("order");
      const std::string o = a.reader.choice(v, a.key("order"), {"position", "velocity", "acceleration", "jerk"});
      if (o == "jerk") {
        if (origin == ConstraintOrigin::Material)
          a.fail("origin", "a jerk-level constraint (order: jerk) is programmed: material constraints have order "
                           "position or velocity (the paper's eq. 2.1, p = 0, 1)");
        return jerk_expression_constraint(a.model, a.entry.name, a.text("expression"), a.reader.params, origin);
      }
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
