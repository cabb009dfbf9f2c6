// Capabilities known at load: what the integrator and the order of the rows ask of the
// constraint kinds and force elements (their exact derivatives over dual numbers, their rates
// at the jerk level) is checked when the scenario is built, with the entry's location and the
// reason, instead of a throw in the middle of a run. Every built-in kind and element is written
// as a law (constraints/law.hpp, ForceLaw in forces/force_elements.hpp) and has both; the checks
// guard kinds written by hand.
#include "build.hpp"

namespace refdyn::build {

namespace {

/// Where constraint `name` was written: its entry, or the URDF (a <mimic> coupling).
std::pair<const SpecValue*, std::string> constraint_location(const ScenarioSpec& spec, const std::string& name) {
  for (const EntrySpec& e : spec.constraints)
    if (e.name == name) return {&e.fields, e.key};
  return {&spec.model.value["urdf"], "model.urdf"};
}

}  // namespace

void check_force_capabilities(const SpecReader& c, const std::vector<EntrySpec>& entries, const ForceSet& forces,
                              bool bdf, bool jerk) {
  const auto& elements = forces.elements();
  const size_t first = elements.size() - entries.size();
  for (size_t k = 0; k < entries.size(); ++k) {
    const ForceElement& f = *elements[first + k];
    if (bdf && !f.exact_derivatives())
      c.fail(entries[k].fields, entries[k].key,
             "force element '" + f.name() + "' has no exact derivatives (apply_dual), which method: bdf needs for the "
             "Jacobian of its implicit steps (hint: method: rk4 or dopri5)");
    if (jerk && !f.has_rate())
      c.fail(entries[k].fields, entries[k].key,
             "force element '" + f.name() + "' in a problem with jerk constraints (order: jerk): the p = 3 "
             "reference dynamics needs the time derivative of every force, which this element does not provide "
             "(damping, spring, effort, flexible_drive and lugre do); remove it or state the task at the "
             "acceleration level");
  }
}

void check_capabilities(const SpecReader& c, const ScenarioSpec& spec, const Problem& s) {
  const bool bdf = s.integrator.method == IntegratorMethod::BDF, jerk = s.is_jerk_problem();
  if (bdf && s.options.paper_literal_forces)
    c.fail(spec.integrator.value["method"], "integrator.method",
           "method: bdf is not available with paper_literal_forces: true: its exact Jacobian would need the "
           "derivative of the projected forces, which contain dQ/dqd themselves (hint: method: rk4 or dopri5, or "
           "paper_literal_forces: false)");
  for (const ConstraintPtr& k : s.constraints.constraints()) {
    const bool needed = bdf || (jerk && k->order() <= 2);
    if (!needed || k->exact_derivatives()) continue;
    const auto [at, key] = constraint_location(spec, k->name);
    c.fail(*at, key,
           "constraint '" + k->name + "' (" + k->describe() + ") has no exact derivatives (evaluate_dual), which " +
               (bdf ? std::string("method: bdf needs for the Jacobian of its implicit steps (hint: method: rk4 or "
                                  "dopri5, or write the constraint as an expression constraint)")
                    : std::string("a problem with jerk constraints (order: jerk) needs for its rows of order "
                                  "position, velocity and acceleration (hint: write the constraint as an expression "
                                  "constraint)")));
  }
  check_force_capabilities(c, spec.forces, s.forces, bdf, jerk);
}

}  // namespace refdyn::build
