// The inputs and the result of a constraint law over Formulas (law.hpp, ConstraintLaw::symbolic):
// the variables the symbolic form names, and the check that a row uses nothing else.
#include "refdyn/constraints/law.hpp"

#include "refdyn/common/error.hpp"

namespace refdyn::law_detail {

namespace {
// A quantity without a variable in the symbolic form (the drift d, ω and its drift, the
// Jacobians): written by law<Formula> into Φ̇, γ or A, which are dropped, never into a row.
const char* const kUnavailable = "<no variable>";
}  // namespace

FormulaInputs formula_inputs(const Model& model, const std::vector<int>& points) {
  FormulaInputs in;
  in.t = Formula::variable("t");
  const int n = model.nq;
  for (int j = 0; j < n; ++j) {
    in.q.push_back(Formula::variable("q(" + model.joint_name[j] + ")"));
    in.qd.push_back(Formula::variable("qd(" + model.joint_name[j] + ")"));
  }
  const Formula none = Formula::variable(kUnavailable);
  in.points.resize(model.point_name.size());
  for (int p : points) {
    const std::string& P = model.point_name.at(static_cast<size_t>(p));
    PointStateT<Formula>& s = in.points[static_cast<size_t>(p)];
    for (int k = 0; k < 3; ++k) {
      const std::string axis(1, "xyz"[k]);
      s.r[k] = Formula::variable(axis + "(" + P + ")");
      s.v[k] = Formula::variable("v" + axis + "(" + P + ")");
      s.d[k] = s.w[k] = s.wd[k] = none;
      for (int c = 0; c < 3; ++c)
        s.R[3 * k + c] = Formula::variable("R" + std::to_string(k + 1) + std::to_string(c + 1) + "(" + P + ")");
    }
    s.C.assign(n, {none, none, none});
    s.Jw.assign(n, {none, none, none});
  }
  return in;
}

SymbolicForm formula_form(const std::vector<Formula>& rows, const FormulaScope& scope, const std::string& kind) {
  SymbolicForm form;
  for (const Formula& r : rows) {
    if (r.text().find(kUnavailable) != std::string::npos)
      throw Error(kind + ": its law writes a row from a quantity the symbolic form has no variable for "
                         "(the acceleration drift, the angular velocity or a Jacobian): no symbolic form");
    form.rows.push_back(r.text());
  }
  form.parameters = scope.parameters;
  form.scenario_texts = scope.scenario_texts;
  return form;
}

}  // namespace refdyn::law_detail
