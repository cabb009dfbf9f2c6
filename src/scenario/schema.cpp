// The scenario file's sections, each declared once (scenario/schema.hpp): the reader's allowed
// keys and choice words, and the key tables of docs/scenario.md, come from the tables below.
// A key is added here, read where its section is read (src/io/scenario.cpp,
// src/io/scenario_sections.cpp, src/scenario/problem.cpp) and documented by `refdyn kinds
// --sections` (paste its output into docs/scenario.md; tests/registry_test.cpp checks the page).
#include "refdyn/scenario/schema.hpp"

#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

namespace refdyn::schema {

namespace {

/// The top level of a scenario file.
Section root_section() {
  return {"", "the file's top level", {
      {"name", "text", "", "the file name", "", "scenario name (default: the file name)", {}},
      {"parameters", "mapping", "", "", "",
       "`name: value` pairs, in order; each may use the ones before it; `pi`, `e`, `deg` and `t` are reserved. A value may "
       "be a list, `v: [0.5, 0.5, …]` (a *list parameter*, below)", {}},
      {"model", "mapping", "yes", "", "", "the mechanism (below)", {}},
      {"constraints", "list", "", "", "", "list of constraints (below); none = an unconstrained forward simulation", {}},
      {"partition", "mapping or `auto`", "", "auto", "",
       "which coordinates are independent (`partition:` below; default: best-conditioned at t0). `refdyn check`, "
       "summary.json (`plan.partition_t0`) and the report show the partition and κ at t0 under either solver. The "
       "solve uses it under `projection` with 2–4 coordinates or as many rows as coordinates; `lagrange` and the "
       "projection's orthonormal basis (every other size) use none, and what is shown is the partition `projection` "
       "takes (and the initial projection's dependent coordinates)", {}},
      {"forces", "list", "", "", "", "force elements acting during planning (below)", {}},
      {"baumgarte", "mapping", "", "", "",
       "the constraint stabilization gains (`baumgarte:` below): Φ̈ + 2αΦ̇ + β²Φ = 0, ċ + β₁c = 0; `kappa` (jerk problems "
       "only): d/dt(NᵀR) = −κ NᵀR", {}},
      {"stabilization", "word or mapping", "", "baumgarte", "",
       "how drift is kept off the constraints: `baumgarte` (default: the gains above), `projection` (no gains: Φ̈ = 0, "
       "ċ = 0, and after every step (q, q̇) is projected onto Φ = 0, Φ̇ = 0, c = 0 by the least change in the mass "
       "metric), or `both`; or a mapping (`stabilization:` below). With `projection`, a `baumgarte:` section is an "
       "error; a problem without position or velocity constraints has nothing to project onto (an error); a "
       "projection that does not converge stops the run (exit 4, the time, residual and rows in summary.json). The "
       "counts `projections` and `max_projection_correction` are in the plan summary (docs/implicit.md)", {}},
      {"solver", "word", "", "auto", "",
       "`projection` (the paper's reduced form), `lagrange` (KKT) or `auto` (default): `lagrange` from 16 coordinates "
       "on, else `projection` (the measured crossover, `kLagrangeFrom` in common/crossovers.hpp; bench/README.md). "
       "Both give the same q̈ to rounding (cond(M)·ε); with `projection` the partition (`independent`) is still "
       "checked and reported, but the solve of models above 4 coordinates does not depend on its conditioning",
       {"projection", "lagrange", "auto"}},
      {"paper_literal_forces", "true | false", "", "false", "",
       "`true`: add the paper's Σ q̇_k ∂Q_k/∂q̇_i terms (not physical; for comparison)", {}},
      {"initial", "mapping", "yes", "", "", "the initial state (`initial:` below)", {}},
      {"integrator", "mapping", "", "", "", "the integration method, span and step (`integrator:` below)", {}},
      {"controller", "mapping", "for track (unless every experiment has one)", "", "",
       "`{type: computed_torque_pd, delta: {joint: δ, …}}` or `{type: pd_gravity, kp: …, kd: …}`", {}},
      {"effort_limit", "mapping", "", "", "", "per-joint saturation `{joint: limit}` for the closed loop", {}},
      {"actuators", "list of joints", "", "every joint", "",
       "`[joint, …]`: the joints that have a motor (default: every joint). Controllers produce effort only there; "
       "every other joint gets exactly zero effort (its `tau_<joint>` column is 0). See \"The plant\" under "
       "experiments", {}},
      {"plant_forces", "list or `none`", "", "", "", "default force elements of the plant (list, or `none`)", {}},
      {"experiments", "list", "for track", "", "", "list of closed-loop runs (below)", {}},
      {"variants", "mapping", "", "", "",
       "a family of tasks: the scenario with some parameters set to a sweep or grid of values, each variant planned "
       "(and tracked) on its own (below)", {}},
      {"optimize", "mapping", "for `refdyn optimize`", "", "",
       "the task parameters to choose (`optimize:` below; docs/optimize.md). `plan`, `track` and `check` check it and "
       "otherwise ignore it", {}},
      {"outputs", "mapping", "", "", "", "`{points: [E, …]}`: points whose positions are written (default: all)", {}},
      {"limits", "mapping", "", "", "",
       "bounds on the work of one scenario, checked before any work (`limits:` below; raise them deliberately)", {}},
      {"time_law", "mapping", "", "", "",
       "`{task_duration: Tp, segments: [d1, …, dK]}` or `{task_duration: Tp, knot_speeds: [v1, …, v_{K−1}]}`: the task "
       "happens on a retimed clock τ = s(t); every function of time of the constraints and force elements is applied "
       "at s(t) (below)", {}},
  }};
}

/// The sections of the solver and the initial state.
std::vector<Section> solver_sections() {
  return {
      {"partition", "`{independent: …}` (or the word `auto`)", {
          {"independent", "list of joints or `auto`", "yes", "", "",
           "the n − m independent coordinates, or `auto`: the best-conditioned at t0", {}},
          {"automatic_switch", "true | false", "", "false", "",
           "re-choose the partition when K_dc becomes ill-conditioned (where the solve uses the partition)", {}},
          {"max_condition", "number > 1", "", "1e8", "",
           "the largest condition number κ(K_dc) = ‖A‖₁ ‖K_dc⁻¹‖₁ (1-norm: largest column sum; A the whole m × n "
           "constraint Jacobian, so a small K_dc beside a large K_ic counts as ill-conditioned even for m = 1; this is "
           "not the 2-norm κ₂ = σ_max/σ_min), where the solve uses the partition; where the projection solves with "
           "its orthonormal basis it bounds the rows' own conditioning instead, max|R_jj| / min|R_jj| of the QR of Aᵀ "
           "(dependent rows stop the run)", {}},
      }},
      {"baumgarte", "Φ̈ + 2αΦ̇ + β²Φ = 0, ċ + β₁c = 0", {
          {"alpha", "number", "", "100", "1/s", "α, the damping of the position rows", {}},
          {"beta", "number", "", "50", "1/s", "β, the stiffness of the position rows", {}},
          {"beta_first_order", "number", "", "50", "1/s", "β₁, the gain of the first-order (velocity) rows", {}},
          {"kappa", "number ≥ 0", "", "50", "1/s",
           "κ, jerk problems only: d/dt(NᵀR) = −κ NᵀR keeps the projected dynamics (docs/higher_order.md)", {}},
      }},
      {"stabilization", "`{method, tolerance, max_iterations}` (or the method alone)", {
          {"method", "word", "yes", "", "", "baumgarte, projection or both (the top-level table)", {"baumgarte", "projection", "both"}},
          {"tolerance", "number", "", "1e-12", "", "the projection's convergence tolerance", {}},
          {"max_iterations", "whole number 1 … 1000", "", "20", "", "the projection's Newton iterations", {}},
      }},
      {"initial", "the state at t0", {
          {"q", "per joint", "yes", "", "rad or m", "all joints (a list in joint order or `{joint: value}`)", {}},
          {"qd", "per joint", "", "0", "rad/s or m/s", "the initial speeds", {}},
          {"qdd", "per joint or mapping", "", "", "rad/s² or m/s²",
           "jerk problems only: all joints, a hint for q̈0, or `{consistent_with: [ROW, …]}` (docs/higher_order.md)", {}},
          {"consistency", "word", "", "check", "",
           "`check` the constraints at t0, or `project` the dependent coordinates onto them (Newton; the correction is "
           "reported by `check`)", {"check", "project"}},
          {"tolerance", "number", "", "1e-8", "", "the largest constraint residual accepted at t0", {}},
      }},
      {"integrator", "the integration of the plan", {
          {"method", "word", "", "rk4", "",
           "rk4, dopri5 or bdf (implicit, for stiff problems: CVODE's BDF with the exact Jacobian; docs/implicit.md)",
           {"rk4", "dopri5", "bdf"}},
          {"step", "number", "", "1e-3", "s",
           "the step; for dopri5 and bdf the output interval unless `output_interval` is set. May not exceed t1 − t0", {}},
          {"t0", "number", "", "0", "s", "the start", {}},
          {"t1", "number or `end`", "", "5", "s", "the end; `end`: the end of the `time_law`", {}},
          {"rtol", "number", "", "1e-8", "", "relative tolerance (dopri5, bdf)", {}},
          {"atol", "number", "", "1e-10", "", "absolute tolerance (dopri5, bdf)", {}},
          {"output_interval", "number", "", "0", "s", "the sampling interval of the outputs; 0: every step", {}},
          {"min_step", "number", "", "min(1e-12, step/2)", "s", "dopri5, bdf: a smaller step means the run has collapsed", {}},
          {"max_order", "whole number 1 … 5", "", "5", "", "bdf only: the highest BDF order", {}},
          {"residual_from", "number", "", "0", "s", "report the max residual for t ≥ this", {}},
          {"residual_tolerance", "number or `none`", "", "1e-3", "",
           "the plan is cut where the constraint residual max |Φ| exceeds it (`none`: no check); see \"Trusting a "
           "plan\" below", {}},
      }},
  };
}

/// experiments:, variants:, their Monte Carlo samples, outputs:, limits: and time_law:.
std::vector<Section> run_sections() {
  return {
      {"experiments[]", "one entry of `experiments:` (below)", {
          {"name", "text", "", "run<k> or run<k>_<i>", "", "the run's name, with `{param}` and `{sample}` (below)", {}},
          {"sweep", "mapping", "", "", "", "`{param: [values]}`: one run per value", {}},
          {"grid", "mapping", "", "", "", "`{p1: [values], p2: [values], …}`: one run per combination", {}},
          {"monte_carlo", "mapping", "", "", "", "`{samples, seed, distributions}`: runs with values drawn at random", {}},
          {"initial", "mapping", "", "the plan's start", "", "`{q: {...}, qd: {...}}`: joints not given start where the plan starts", {}},
          {"plant_forces", "list or `none`", "", "the top-level `plant_forces`", "", "the plant's force elements", {}},
          {"controller", "mapping", "", "the top-level `controller`", "", "same keys as the top-level `controller`", {}},
      }},
      {"experiments[].initial", "an experiment's start", {
          {"q", "per joint", "", "the plan's", "rad or m", "initial positions of the joints given", {}},
          {"qd", "per joint", "", "the plan's", "rad/s or m/s", "initial speeds of the joints given", {}},
      }},
      {"monte_carlo", "an experiment's `monte_carlo:`", {
          {"samples", "whole number ≥ 1", "yes", "", "", "N, the number of runs", {}},
          {"seed", "whole number 0 … 2^64 − 1", "yes", "", "", "the seed of the generator, written in digits", {}},
          {"distributions", "mapping", "yes", "", "",
           "`{p: {normal: {mean: μ, std: σ}}}` (σ ≥ 0) or `{p: {uniform: {low: a, high: b}}}` (a ≤ b), in the order drawn", {}},
      }},
      {"monte_carlo.distributions.<p>", "the distribution of parameter p: exactly one of", {
          {"normal", "mapping", "", "", "", "`{mean, std}`: a normal distribution", {}},
          {"uniform", "mapping", "", "", "", "`{low, high}`: a uniform distribution", {}},
      }},
      {"monte_carlo.distributions.<p>.normal", "a normal distribution (p's unit)", {
          {"mean", "number", "yes", "", "", "μ", {}},
          {"std", "number ≥ 0", "yes", "", "", "σ", {}},
      }},
      {"monte_carlo.distributions.<p>.uniform", "a uniform distribution on [low, high] (p's unit)", {
          {"low", "number", "yes", "", "", "a", {}},
          {"high", "number ≥ low", "yes", "", "", "b", {}},
      }},
      {"variants", "a family of tasks (below)", {
          {"name", "text", "", "v<k>", "", "the variant's folder name, with `{param}` as for experiments", {}},
          {"sweep", "mapping", "", "", "", "`{param: [values]}`: one variant per value", {}},
          {"grid", "mapping", "", "", "", "`{p1: [values], p2: [values], …}`: the cartesian product, first parameter slowest", {}},
      }},
      {"outputs", "what the plan records besides the state", {
          {"points", "list of points", "", "all", "", "the points whose positions are written", {}},
      }},
      {"limits", "bounds checked before any work", {
          {"max_steps", "whole number", "", "2000000", "", "integration steps of one run", {}},
          {"max_samples", "whole number", "", "1000000", "", "recorded samples of one run", {}},
          {"max_runs", "whole number ≤ 100000", "", "10000", "",
           "closed-loop runs (or variants) after expanding sweeps, grids and Monte Carlo samples", {}},
      }},
      {"time_law", "a retimed clock τ = s(t) (below)", {
          {"task_duration", "number > 0", "yes", "", "s", "Tp, the task's own span [0, Tp]", {}},
          {"segments", "list of numbers > 0", "", "", "s", "d1 … dK: real durations of K equal parts of task time", {}},
          {"knot_speeds", "list of numbers > 0", "", "", "", "v1 … v_{K−1}: the task's speeds ṡ at the inner knots (instead of `segments`)", {}},
      }},
  };
}

/// optimize: and its parts; model.urdf:.
std::vector<Section> optimize_sections() {
  return {
      {"optimize", "the task parameters to choose (docs/optimize.md)", {
          {"variables", "list", "yes", "", "", "`{name, lower, upper, start}` per variable", {}},
          {"objective", "mapping", "yes", "", "",
           "`{minimize: EXPR}` or `{maximize: EXPR}`, EXPR of plan metrics, variables and parameters", {}},
          {"constraints", "mapping", "", "", "", "`{feasible: true, bounds: [{expression, lower, upper}]}`", {}},
          {"method", "word", "", "slsqp", "", "the optimizer (docs/optimize.md)", {"slsqp", "mma", "cobyla", "bobyqa", "phase_plane"}},
          {"tolerance", "mapping", "", "", "", "`{x, f}`: relative stopping tolerances", {}},
          {"budget", "whole number > 0", "", "100", "", "the most plans evaluated", {}},
      }},
      {"optimize.variables[]", "one variable", {
          {"name", "text", "yes", "", "", "a parameter of the scenario", {}},
          {"lower", "number", "yes", "", "", "its lower bound", {}},
          {"upper", "number", "yes", "", "", "its upper bound", {}},
          {"start", "number", "", "the parameter's value", "", "the first candidate", {}},
      }},
      {"optimize.constraints", "what a candidate must satisfy", {
          {"feasible", "true | false", "", "false", "", "the plan must respect the joint limits", {}},
          {"bounds", "list", "", "", "", "`{expression, lower and/or upper}` per bound", {}},
      }},
      {"optimize.constraints.bounds[]", "one bound", {
          {"expression", "text", "yes", "", "", "an expression of plan metrics, variables and parameters", {}},
          {"lower", "number", "", "", "", "its lower bound (a lower or an upper bound is required)", {}},
          {"upper", "number", "", "", "", "its upper bound", {}},
      }},
      {"optimize.tolerance", "the relative stopping tolerances", {
          {"x", "number ≥ 0", "", "1e-6", "", "on the variables", {}},
          {"f", "number ≥ 0", "", "1e-9", "", "on the objective", {}},
      }},
  };
}

/// The model section's own tables (read in src/scenario/model_section.cpp).
std::vector<Section> model_sections() {
  const Key inertia{"inertia", "[Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] or a 3×3 list", "", "0", "kg m²",
                    "about the centre of mass, in link axes", {}};
  const Key mass{"mass", "number ≥ 0", "", "0", "kg", "the link's mass", {}};
  const Key limits{"limits", "mapping", "", "none", "", "the joint's limits (`model.dh.joints[].limits` below)", {}};
  const Key armature{"armature", "number ≥ 0", "", "0", "kg m² (kg: prismatic)",
                     "rotor inertia reflected to the joint, I_r N² (or under `model.armature`)", {}};
  return {
      {"model", "the mechanism: exactly one of `dh`, `links`, `urdf`", {
          {"name", "text", "", "the scenario's name", "", "the model's name", {}},
          {"gravity", "[x, y, z]", "", "[0, 0, -9.81]", "m/s²", "gravity in the world frame", {}},
          {"base", "pose", "", "identity", "", "the base frame's pose in the world (`{xyz, rpy}`)", {}},
          {"dh", "mapping", "", "", "", "a serial chain by Denavit–Hartenberg rows (`model.dh` below)", {}},
          {"links", "list", "", "", "", "links with joint origins (`model.links[]` below)", {}},
          {"urdf", "mapping", "", "", "", "a URDF file (`model.urdf` below)", {}},
          {"points", "mapping", "", "", "", "`{name: {link, position}}`: named points (`model.points.<name>` below)", {}},
          {"armature", "mapping", "", "", "", "`{joint: a}`: a joint's armature for any model (replaces a URDF's)", {}},
      }},
      {"model.dh", "a serial chain by DH rows; the joint variable is added to θ (revolute) or d (prismatic)", {
          {"convention", "word", "", "standard", "", "`standard` or `modified` DH", {"standard", "modified"}},
          {"joints", "list", "yes", "", "", "one row per joint, base to tip (`model.dh.joints[]` below)", {}},
      }},
      {"model.dh.joints[]", "one DH row: a joint and the link it moves", {
          {"name", "text", "yes", "", "", "the joint's name", {}},
          {"link", "text", "", "the joint's name", "", "the link's name", {}},
          {"type", "word", "yes", "", "", "`revolute`, `prismatic` or `fixed`", {"revolute", "prismatic", "fixed"}},
          {"theta", "number", "", "0", "rad", "θ", {}},
          {"d", "number", "", "0", "m", "d", {}},
          {"a", "number", "", "0", "m", "a", {}},
          {"alpha", "number", "", "0", "rad", "α", {}},
          mass,
          {"com", "[x, y, z]", "", "[0, 0, 0]", "m", "the centre of mass in the link's DH frame", {}},
          inertia, limits, armature,
      }},
      {"model.links[]", "one link and the joint that moves it", {
          {"name", "text", "yes", "", "", "the link's name", {}},
          {"joint", "text", "", "the link's name", "", "the joint's name", {}},
          {"parent", "link or `base`", "", "base", "", "a link listed before, or `base` (`world`)", {}},
          {"type", "word", "yes", "", "", "`revolute`, `prismatic` or `fixed`", {"revolute", "prismatic", "fixed"}},
          {"axis", "[x, y, z]", "", "[0, 0, 1]", "", "the joint axis in the joint frame (normalized)", {}},
          {"origin", "pose", "", "identity", "", "the joint frame in the parent link's frame", {}},
          {"link_offset", "pose", "", "identity", "", "the link frame in the moved joint frame", {}},
          {"offset", "number", "", "0", "rad or m", "added to the joint variable", {}},
          mass,
          {"com", "[x, y, z]", "", "[0, 0, 0]", "m", "the centre of mass in the link frame", {}},
          inertia, limits, armature,
      }},
      {"model.dh.joints[].limits", "a joint's limits, here and under `model.links[]` (leave one out: unlimited)", {
          {"lower", "number", "", "−∞", "rad or m", "lowest position", {}},
          {"upper", "number", "", "+∞", "rad or m", "highest position", {}},
          {"velocity", "number ≥ 0", "", "∞", "rad/s or m/s", "largest speed", {}},
          {"effort", "number ≥ 0", "", "∞", "N m or N", "largest effort", {}},
      }},
      {"model.points.<name>", "one named point: `points: {name: {link, position}}`", {
          {"link", "link, `world` or `base`", "yes", "", "", "the link it is fixed to", {}},
          {"position", "[x, y, z]", "", "[0, 0, 0]", "m", "in that link's frame", {}},
      }},
      {"model.urdf", "a model read from a URDF file (`model:` below)", {
          {"file", "path", "yes", "", "", "the URDF file, relative to the scenario file", {}},
          {"root", "link", "", "the URDF's root", "", "the link taken as the base", {}},
          {"packages", "mapping", "", "", "", "`{package: folder}` for `package://` paths, folders relative to the scenario file", {}},
          {"dynamics", "true | false", "", "false", "",
           "true: each joint's `<dynamics damping friction>` becomes force elements (`model:` below)", {}},
      }},
  };
}

/// Value forms any section may use: a function of t written as a mapping, a pose.
std::vector<Section> value_forms() {
  return {
      {"function of t", "a function of t written as a mapping (else a number or an expression in t)", {
          {"cycloidal", "mapping", "", "", "", "`{rise, duration, from, start}`: a cycloidal rise", {}},
          {"raised_cosine", "mapping", "", "", "", "`{base, amplitude, period}`: base + amplitude·(1 − cos(2πt/period))/2", {}},
      }},
      {"function of t.cycloidal", "from `from` to `from + rise` over [start, start + duration], zero speed and acceleration at both ends", {
          {"rise", "number", "yes", "", "", "the change of the value (the function's unit)", {}},
          {"duration", "number > 0", "yes", "", "s", "the time the rise takes", {}},
          {"from", "number", "", "0", "", "the value before the rise (the function's unit)", {}},
          {"start", "number", "", "0", "s", "when the rise starts", {}},
      }},
      {"function of t.raised_cosine", "base + amplitude·(1 − cos(2πt/period))/2", {
          {"base", "number", "yes", "", "", "the value at t = 0 (the function's unit)", {}},
          {"amplitude", "number", "yes", "", "", "the largest change (the function's unit)", {}},
          {"period", "number > 0", "yes", "", "s", "the period", {}},
      }},
      {"pose", "a frame's pose in its parent (`base`, a link's `origin`)", {
          {"xyz", "[x, y, z]", "", "[0, 0, 0]", "m", "the position", {}},
          {"rpy", "[roll, pitch, yaw]", "", "[0, 0, 0]", "rad", "the orientation, R = Rz(yaw) Ry(pitch) Rx(roll) (URDF)", {}},
      }},
  };
}

std::vector<Section> all_sections() {
  std::vector<Section> all{root_section()};
  for (auto* part : {&solver_sections, &run_sections, &model_sections, &optimize_sections, &value_forms})
    for (Section& s : part()) all.push_back(std::move(s));
  return all;
}

/// A markdown table cell: '|' escaped.
std::string cell(const std::string& s) {
  std::string out;
  for (char ch : s) {
    if (ch == '|') out += '\\';
    out += ch;
  }
  return out;
}

std::string type_text(const Key& k) {
  if (k.choices.empty()) return k.type;
  std::string t;
  for (const std::string& c : k.choices) t += (t.empty() ? "`" : " | `") + c + "`";
  return t;
}

}  // namespace

const std::vector<Section>& sections() {
  static const std::vector<Section> all = all_sections();
  return all;
}

const Section& section(std::string_view path) {
  for (const Section& s : sections())
    if (s.path == path) return s;
  throw std::logic_error("scenario schema: no section '" + std::string(path) + "' is declared");
}

const std::vector<std::string>& keys(std::string_view path) {
  static const std::map<std::string, std::vector<std::string>, std::less<>> names = [] {
    std::map<std::string, std::vector<std::string>, std::less<>> m;
    for (const Section& s : sections()) {
      std::vector<std::string>& v = m[s.path];
      for (const Key& k : s.keys) v.push_back(k.name);
    }
    return m;
  }();
  const auto it = names.find(path);
  if (it == names.end()) throw std::logic_error("scenario schema: no section '" + std::string(path) + "' is declared");
  return it->second;
}

const Key& key(std::string_view path, std::string_view name) {
  for (const Key& k : section(path).keys)
    if (k.name == name) return k;
  throw std::logic_error("scenario schema: no key '" + std::string(name) + "' is declared in '" + std::string(path) + "'");
}

const std::vector<std::string>& choices(std::string_view path, std::string_view name) { return key(path, name).choices; }

std::string markdown() {
  std::ostringstream os;
  for (const Section& s : sections()) {
    if (s.path.empty()) {
      os << "| key | required | meaning |\n|---|---|---|\n";
      for (const Key& k : s.keys)
        os << "| `" << k.name << "` | " << cell(k.required.empty() ? "no" : k.required) << " | " << cell(k.doc) << " |\n";
      os << "\n### The keys of each section\n\nLast, the mappings a value may be written as (a function of t, a pose). A "
            "default is what an absent key means; a unit is that of the number as written (a per-joint value: of a "
            "revolute or a prismatic joint).\n";
      continue;
    }
    os << "\n#### `" << s.path << "` — " << s.doc << "\n\n| key | type | required | default | unit | meaning |\n|---|---|---|---|---|---|\n";
    for (const Key& k : s.keys)
      os << "| `" << k.name << "` | " << cell(type_text(k)) << " | " << cell(k.required.empty() ? "no" : k.required) << " | "
         << cell(k.default_text) << " | " << cell(k.unit) << " | " << cell(k.doc) << " |\n";
  }
  return os.str();
}

}  // namespace refdyn::schema
