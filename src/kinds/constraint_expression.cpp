#include "kinds.hpp"

namespace refdyn::kinds {

ConstraintKind constraint_expression() {
  ConstraintKind k;
  k.name = "expression";
  k.doc = "a constraint written as an expression over x(P), y(P), z(P), q(joint), t and the parameters "
          "(first order: also vx(P), vy(P), vz(P), qd(joint)); exact derivatives (GiNaC). Written as "
          "`expression: TEXT` (the `kind:` key may be omitted).";
  k.keys = {{"expression", "text", true, "", "the constraint function, = 0"},
            {"order", "position | velocity", false, "position", "holonomic Φ(q, t) = 0 or first-order c(q, q̇, t) = 0"}};
  k.build = [](const EntryArgs& a, ConstraintOrigin origin) {
    bool first = false;
    if (a.has("order")) first = a.reader.choice(a.value("order"), a.key("order"), {"position", "velocity"}) == "velocity";
    return expression_constraint(a.model, a.entry.name, a.text("expression"), first, a.reader.params, origin);
  };
  return k;
}

}  // namespace refdyn::kinds
