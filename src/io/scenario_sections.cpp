// The variants: and optimize: sections of a scenario file → their specs (scenario_sections.hpp).
// Structure only: numbers and expressions stay text for the layers that evaluate them.
#include "scenario_sections.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/scenario/schema.hpp"

#include <string>
#include <utility>

namespace refdyn::io::detail {

/// variants: (a sweep or a grid of parameters).
VariantsSpec read_variants(const SpecReader& c, const SpecValue& va) {
  VariantsSpec v;
  v.value = va;
  c.keys(va, "variants", schema::keys("variants"));
  if (va["name"]) {
    v.name = c.string(va["name"], "variants.name");
    v.named = true;
  }
  const SpecValue& sw = va["sweep"];
  const SpecValue& gr = va["grid"];
  if (sw && gr) c.fail(gr, "variants.grid", "give one of sweep and grid (sweep: one parameter; grid: several)");
  if (!sw && !gr) c.fail(va, "variants", "expected sweep: {parameter: [values]} or grid: {p1: [values], p2: [values]}");
  const SpecValue& g = sw ? sw : gr;
  const std::string gkey = sw ? "variants.sweep" : "variants.grid";
  if (!g.is_map() || g.size() == 0 || (sw && g.size() != 1))
    c.fail(g, gkey, sw ? "expected one entry  parameter: [values]" : "expected parameter: [values] entries");
  for (const auto& e : g.entries) {
    if (!e.value.is_list() || e.value.size() == 0) c.fail(e.value, gkey + "." + e.key, "expected a non-empty list of values");
    v.grid.emplace_back(e.key, e.value.items);
  }
  return v;
}

/// optimize: (refdyn optimize, docs/optimize.md): the structure; names, bounds and expressions
/// are checked by the optimize layer (check_optimize).
OptimizeSpec read_optimize(const SpecReader& c, const SpecValue& op, const SourceLocation& at) {
  OptimizeSpec o;
  o.value = op;
  if (!op.is_map()) c.fail(op.where.line ? op.where : at, "optimize", "expected a mapping with variables, objective (and constraints, method, tolerance, budget), got " + op.describe());
  c.keys(op, "optimize", schema::keys("optimize"));
  const SpecValue& vars = c.need(op, "variables", "optimize");
  if (!vars.is_list() || vars.size() == 0)
    c.fail(vars.where.line ? vars.where : op.key_location("variables"), "optimize.variables",
           "expected a non-empty list of {name, lower, upper[, start]}, got " +
               (vars.is_list() ? std::string("an empty list") : vars.describe()));
  for (size_t i = 0; i < vars.size(); ++i) {
    OptimizeVariableSpec v;
    v.key = "optimize.variables[" + std::to_string(i) + "]";
    v.value = vars[i];
    if (!vars[i].is_map()) c.fail(vars[i], v.key, "expected a mapping {name, lower, upper[, start]}, got " + vars[i].describe());
    c.keys(vars[i], v.key, schema::keys("optimize.variables[]"));
    v.name = c.string(c.need(vars[i], "name", v.key), v.key + ".name");
    v.lower = c.need(vars[i], "lower", v.key);
    v.upper = c.need(vars[i], "upper", v.key);
    v.start = vars[i]["start"];
    o.variables.push_back(std::move(v));
  }
  const SpecValue& obj = c.need(op, "objective", "optimize");
  if (!obj.is_map() || obj.size() != 1 || (!obj["minimize"] && !obj["maximize"]))
    c.fail(obj.where.line ? obj.where : op.key_location("objective"), "optimize.objective",
           "expected {minimize: EXPRESSION} or {maximize: EXPRESSION}, got " + obj.describe());
  o.maximize = static_cast<bool>(obj["maximize"]);
  o.objective_value = o.maximize ? obj["maximize"] : obj["minimize"];
  o.objective = c.string(o.objective_value, std::string("optimize.objective.") + (o.maximize ? "maximize" : "minimize"));
  if (const SpecValue& cs = op["constraints"]) {
    c.keys(cs, "optimize.constraints", schema::keys("optimize.constraints"));
    if (cs["feasible"]) o.feasible = c.boolean(cs["feasible"], "optimize.constraints.feasible");
    if (const SpecValue& bs = cs["bounds"]) {
      if (!bs.is_list()) c.fail(bs, "optimize.constraints.bounds", "expected a list of {expression, lower and/or upper}, got " + bs.describe());
      for (size_t i = 0; i < bs.size(); ++i) {
        OptimizeBoundSpec b;
        b.key = "optimize.constraints.bounds[" + std::to_string(i) + "]";
        b.value = bs[i];
        if (!bs[i].is_map()) c.fail(bs[i], b.key, "expected a mapping {expression, lower and/or upper}, got " + bs[i].describe());
        c.keys(bs[i], b.key, schema::keys("optimize.constraints.bounds[]"));
        b.expression = c.string(c.need(bs[i], "expression", b.key), b.key + ".expression");
        b.lower = bs[i]["lower"];
        b.upper = bs[i]["upper"];
        if (!b.lower && !b.upper) c.fail(bs[i], b.key, "expected a lower or an upper bound (or both)");
        o.bounds.push_back(std::move(b));
      }
    }
  }
  if (const SpecValue& m = op["method"]) {
    o.method = c.choice(m, "optimize.method", schema::choices("optimize", "method"));
    o.method_value = m;
  }
  if (const SpecValue& t = op["tolerance"]) {
    c.keys(t, "optimize.tolerance", schema::keys("optimize.tolerance"));
    o.tolerance_x = t["x"];
    o.tolerance_f = t["f"];
  }
  o.budget = op["budget"];
  return o;
}

}  // namespace refdyn::io::detail
