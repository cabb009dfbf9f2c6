#pragma once
// Private to src/scenario/ (not installed): the section builders of build_problem that live in
// their own files, and the helpers the files share. problem.cpp holds build_problem and the
// other sections; model_section.cpp the model; initial_section.cpp the initial state and the
// checks at t0; experiments.cpp the experiments.

#include "refdyn/scenario/problem.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"
#include "refdyn/scenario/registry.hpp"

#include <memory>
#include <string>
#include <vector>

namespace refdyn::build {

/// model: the Problem with its model, names and parameters (every name checked).
std::unique_ptr<Problem> build_model_section(const SpecReader& c, const ScenarioSpec& spec);
/// experiments: each expanded (sweep, grid, Monte Carlo) into named Experiments.
void build_experiments(const SpecReader& c, const ScenarioSpec& spec, Problem& s);
/// initial: q0, q̇0 (and q̈0, κ for jerk problems) as written (initial_section.cpp).
void build_initial(const SpecReader& c, const ScenarioSpec& spec, Problem& s);
/// The initial state at t0 (after the integrator and limits): consistent with the constraints
/// (projected when asked), the partition chosen, everything a run evaluates at t0 finite and the
/// rows independent (initial_section.cpp).
void check_initial_state(const SpecReader& c, const ScenarioSpec& spec, Problem& s);

// Shared helpers (defined in problem.cpp).
/// `s` with every "{var}" replaced by v (%g).
std::string substitute(std::string s, const std::string& var, double v);
/// Runs an experiment expands into, as a double; checks a Monte Carlo `samples`.
double experiment_runs(const SpecReader& c, const ExperimentSpec& e);
/// Reads a force list (signal columns suffixed, names checked) into `out`.
void read_forces(const SpecReader& c, const std::vector<EntrySpec>& entries, const Model& m, ForceSet& out);
/// A count for messages: a whole number when it fits, else in exponent form.
std::string count_text(double x);
/// Names become CSV headers, JSON strings and file names: printable UTF-8.
void check_name(const SpecReader& c, const SpecValue& at, const std::string& key, const std::string& name);

/// Capabilities known at load (capabilities.cpp): each force element built from `entries` (the
/// last entries.size() elements of `forces`) has exact derivatives when `bdf` and its rate when
/// `jerk`; otherwise a located error with the reason.
void check_force_capabilities(const SpecReader& c, const std::vector<EntrySpec>& entries, const ForceSet& forces,
                              bool bdf, bool jerk);
/// The problem's (after its integrator): under method: bdf every constraint and force element has
/// exact derivatives and paper_literal_forces is off; in a jerk-level problem every force element
/// has its rate and every row of order position, velocity or acceleration exact derivatives.
void check_capabilities(const SpecReader& c, const ScenarioSpec& spec, const Problem& s);

/// Builds one registry entry; errors from the factory that carry no location get the entry's.
template <class Kind, class Build>
auto build_entry(const SpecReader& c, const Registry<Kind>& reg, const EntrySpec& e, const std::string& kind_key,
                 const Build& build) {
  const Kind* k = reg.find(e.kind);
  if (!k)
    c.fail(e.fields[kind_key].is_null() ? e.fields : e.fields[kind_key], e.key + "." + kind_key,
           "got '" + e.kind + "', expected one of the " + reg.what() + "s" + did_you_mean(e.kind, reg.names()));
  try {
    return build(*k);
  } catch (const Error& err) {
    const std::string w = err.what();
    if (w.rfind(c.file(), 0) == 0) throw;  // already located
    c.fail(e.fields, e.key, w);
  }
}

}  // namespace refdyn::build
