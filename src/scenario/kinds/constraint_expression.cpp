#include "kinds.hpp"

#include "refdyn/common/error.hpp"
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
             "(programmed, p = 2) or jerk-level B(t, q, q̇) q⃛ + s = 0 (programmed, p = 3, any other rows and force elements beside it); docs/higher_order.md"},
            {"differentiate", "true | false", false, "false",
             "true: `expression` is written one order lower (a position expression for order: velocity, a "
             "velocity expression for order: acceleration, an acceleration expression for order: jerk) and "
             "refdyn forms its exact time derivative (GiNaC); a jerk row made so can give a consistent initial "
             "acceleration (initial.qdd: {consistent_with: NAME})"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    ConstraintOrder order = ConstraintOrder::Position;
    const bool differentiate = a.has("differentiate") && a.reader.boolean(a.value("differentiate"), a.key("differentiate"));
    std::string text = a.text("expression");
    if (a.reader.time_law && uses_identifier(text, "t"))
      a.fail("expression", "an expression constraint in t is not retimed by the scenario's time_law (hint: write "
                           "the function of time with a `function:` key, e.g. kind: point_coordinate or "
                           "joint_trajectory, which the time law applies to)");
    std::string o = "position";
    if (a.has("order")) o = a.reader.choice(a.value("order"), a.key("order"), {"position", "velocity", "acceleration", "jerk"});
    if (differentiate) {
      if (o == "position")
        a.fail("differentiate", "differentiate: true forms the time derivative of the expression, one order higher; "
                                "with order: position there is no lower order to start from (hint: set order: "
                                "velocity, acceleration or jerk)");
      try {
        if (o != "jerk") text = differentiate_expression_text(a.model, a.entry.name, text, a.reader.params);
      } catch (const Error& e) {
        a.fail("expression", e.what());
      }
    }
    if (o == "jerk") {
      if (origin == ConstraintOrigin::Material)
        a.fail("origin", "a jerk-level constraint (order: jerk) is programmed: material constraints have order "
                         "position or velocity (the paper's eq. 2.1, p = 0, 1)");
      if (differentiate) return differentiated_jerk_constraint(a.model, a.entry.name, text, a.reader.params, origin);
      return jerk_expression_constraint(a.model, a.entry.name, text, a.reader.params, origin);
    }
    order = o == "velocity" ? ConstraintOrder::Velocity
            : o == "acceleration" ? ConstraintOrder::Acceleration : ConstraintOrder::Position;
    if (order == ConstraintOrder::Acceleration && origin == ConstraintOrigin::Material)
      a.fail("origin", "an acceleration-level constraint (order: acceleration) is programmed: material constraints "
                       "have order position or velocity (the paper's eq. 2.1, p = 0, 1)");
    return expression_constraint(a.model, a.entry.name, text, order, a.reader.params, origin);
  };
  return k;
}

}  // namespace refdyn::kinds
