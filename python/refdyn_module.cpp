// The compiled part of the Python package `refdyn` (module refdyn._refdyn). The pure-Python
// part (python/refdyn/__init__.py) wraps it: Trajectory dataclass, scenario from a dict, progress.
//
//   Problem (io::load_problem / io::parse_problem) ──run──▶ Results (io::run_problem)
//     .plan / .runs: trajectory tables (io::trajectory_table) as (column names, float64 array)
//     .feasibility_json / .summary_json: the JSON text the CLI writes (json.loads'ed in Python)
//   Model: the model functions on one Data workspace (FK, point Jacobian, M, c + g, ID, FD).
//   check (io::check_scenario) → a dict; generate (generate_symbolic) → the texts;
//   run_variants (io::run_variants) → per-variant summaries, variants.csv, summary.json.
//
// Errors: refdyn::Error → refdyn.Error (a ValueError), refdyn::NumericalFailure →
// refdyn.NumericalFailure (a refdyn.Error), message unchanged. Runs release the GIL.

#include "refdyn/constraints/constraints.hpp"
#include "refdyn/common/error.hpp"
#include "refdyn/common/fields.hpp"
#include "refdyn/common/json.hpp"
#include "refdyn/simulate/feasibility.hpp"
#include "refdyn/io/check.hpp"
#include "refdyn/io/output.hpp"
#include "refdyn/io/results.hpp"
#include "refdyn/io/scenario.hpp"
#include "refdyn/io/urdf.hpp"
#include "refdyn/io/variants.hpp"
#include "refdyn/optimize/optimize.hpp"
#include "refdyn/simulate/metrics.hpp"
#include "refdyn/symbolic/sensitivity.hpp"
#include "refdyn/symbolic/symbolic.hpp"
#include "refdyn/multibody/kinematics.hpp"
#include "refdyn/multibody/model.hpp"
#include "refdyn/scenario/problem.hpp"
#include "refdyn/multibody/recursive_dynamics.hpp"
#include "refdyn/reference/reference_dynamics.hpp"

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace py = pybind11;
using namespace pybind11::literals;
using namespace refdyn;

namespace {

using Vec = Eigen::VectorXd;

// ---------------------------------------------------------------- trajectories
/// A trajectory table as (column names, float64 array of shape (samples, columns)).
py::tuple table_of(const Trajectory& tr) {
  const io::CsvTable tab = io::trajectory_table(tr);
  const py::ssize_t rows = static_cast<py::ssize_t>(tab.rows.size());
  const py::ssize_t cols = static_cast<py::ssize_t>(tab.header.size());
  py::array_t<double> a({rows, cols});
  auto m = a.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < rows; ++i) {
    const auto& r = tab.rows[static_cast<size_t>(i)];
    for (py::ssize_t j = 0; j < cols; ++j) m(i, j) = r[static_cast<size_t>(j)];
  }
  return py::make_tuple(tab.header, a);
}

/// Python values of described fields (common/fields.hpp): numbers, text, enums as their names,
/// structs as dicts of their sink::Python fields, named values as dicts, an empty optional as
/// None (or no key: OmitIfEmpty), vectors as lists.
template <class V>
py::object py_of(const V& v);

template <class T>
py::dict py_dict(const T& x) {
  py::dict d;
  for_each_field<T>([&](const auto& f) {
    if ((f.in & sink::Python) && !omitted(f, x)) d[f.name] = py_of(f.get(x));
  });
  return d;
}

template <class V>
py::object py_of(const V& v) {
  if constexpr (std::is_enum_v<V>) {
    return py::str(to_string(v));
  } else if constexpr (is_described_v<V>) {
    return py_dict(v);
  } else if constexpr (std::is_arithmetic_v<V> || std::is_same_v<V, std::string>) {
    return py::cast(v);
  } else if constexpr (is_optional<V>::value) {
    return v ? py_of(*v) : py::none();
  } else if constexpr (is_named<V>::value) {
    py::dict d;
    for (const auto& [name, x] : v) d[py::str(name)] = py_of(x);
    return d;
  } else {
    py::list l;
    for (const auto& e : v) l.append(py_of(e));
    return l;
  }
}

/// An integration's summary (IntegrationSummary's fields) and "ok".
py::dict summary_of(const IntegrationSummary& s) {
  py::dict d = py_dict(s);
  d["ok"] = s.ok();
  return d;
}

/// The layout of a trajectory (what the columns group into).
py::dict layout_of(const Trajectory& tr) {
  py::dict d;
  d["joints"] = tr.joints;
  d["points"] = tr.points;
  d["state_names"] = tr.state_names;
  d["constraint_rows"] = tr.constraint_rows;
  d["target_signals"] = tr.target_signals;
  d["force_signals"] = tr.force_signals;
  return d;
}

// ---------------------------------------------------------------- progress
/// Progress for io::run_problem: a Python callable progress(what, t, t0, t1), called with the
/// GIL held at most ~100 times per run (and once at the end), or none.
io::ProgressFactory progress_factory(const py::object& callback) {
  if (callback.is_none()) return {};
  auto cb = std::make_shared<py::object>(callback);
  return [cb](const std::string& what, double t0, double t1) -> std::function<void(double)> {
    auto next = std::make_shared<double>(t0);
    const double dt = (t1 - t0) / 100.0;
    return [cb, what, t0, t1, next, dt](double t) {
      if (t < *next && t < t1) return;
      *next = t + dt;
      py::gil_scoped_acquire gil;
      (*cb)(what, t, t0, t1);
    };
  };
}

// ---------------------------------------------------------------- model
/// A compiled Model and one workspace. Arguments are copied into per-model scratch vectors (no
/// allocation when their size is right; a wrong size reaches the library's own check and
/// message); results are returned as new NumPy arrays.
using Arr = py::array_t<double, py::array::c_style | py::array::forcecast>;

struct PyModel {
  explicit PyModel(const Model& m) : model(std::make_shared<const Model>(m)), data(*model) {}
  std::shared_ptr<const Model> model;
  Data data;
  Vec a[3];  // scratch for q, qd, qdd / tau

  const Vec& arg(int slot, const Arr& x, const char* what) {
    if (x.ndim() != 1)
      throw Error(std::string(what) + ": expected a 1-D array, got " + std::to_string(x.ndim()) + " dimensions");
    Vec& v = a[slot];
    if (v.size() != x.shape(0)) v.resize(x.shape(0));
    std::copy(x.data(), x.data() + x.shape(0), v.data());
    return v;
  }
  void fk(const Arr& q) { forward_kinematics(*model, data, arg(0, q, "q")); }
};

py::array_t<double> out(const Vec& v) {
  py::array_t<double> r(v.size());
  std::copy(v.data(), v.data() + v.size(), r.mutable_data());
  return r;
}

template <typename Derived>
py::array_t<double> out(const Eigen::MatrixBase<Derived>& m) {
  py::array_t<double> r({m.rows(), m.cols()});
  auto w = r.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) w(i, j) = m(i, j);
  return r;
}

/// {lower, upper, velocity, effort} (Fields<JointLimits>, as in feasibility.json).
py::dict limits_dict(const JointLimits& l) { return py_dict(l); }

std::shared_ptr<PyModel> urdf_model(const ModelDescription& d) { return std::make_shared<PyModel>(build_model(d)); }

io::UrdfOptions urdf_options(const std::string& root_link, bool points_for_links) {
  io::UrdfOptions o;
  o.root_link = root_link;
  o.points_for_links = points_for_links;
  return o;
}

// ---------------------------------------------------------------- problems and results
struct PyResults {
  std::shared_ptr<const Problem> problem;  // the Results' planner refers to it
  io::Results results;
};

std::shared_ptr<PyResults> run(const std::shared_ptr<const Problem>& problem, bool track, const py::object& progress,
                               int jobs) {
  if (track && problem->experiments.empty())
    throw Error(problem->file + ": experiments: missing or an empty list (track needs at least one experiment; see docs/scenario.md)");
  io::RunOptions o;
  o.track = track;
  o.progress = progress_factory(progress);
  if (jobs < 0) throw Error("jobs: expected 0 (every core) or a number of threads >= 1, got " + std::to_string(jobs));
  o.jobs = jobs;
  auto r = std::make_shared<PyResults>();
  r->problem = problem;
  {
    py::gil_scoped_release release;
    r->results = io::run_problem(*problem, o);
  }
  return r;
}

// ---------------------------------------------------------------- scenario texts
/// The scenario of a path (is_text false) or of YAML text named source_name.
/// A scenario's optimize: section checked as `refdyn plan` checks it (the whole file is valid or
/// an error, with the command's message).
void check_optimize_of(const ScenarioSpec& spec, const Problem& problem) {
  if (spec.optimize) (void)check_optimize(spec, problem);
}

ScenarioSpec scenario_spec(const std::string& source, bool is_text, const std::string& source_name) {
  return is_text ? io::parse_scenario(source, source_name) : io::load_scenario(source);
}

// ---------------------------------------------------------------- check
/// What `refdyn check` reports, as a dict: Fields<io::CheckReport> (io/check.hpp), the same
/// fields `refdyn check --json` writes, plus the command's text.
py::dict check_dict(const io::CheckReport& r) { return py_dict(r); }

// ---------------------------------------------------------------- generate
py::dict generate(const Problem& problem, bool c, bool latex, bool json, const std::string& prefix) {
  SymbolicOptions opt;
  opt.prefix = prefix;
  std::vector<std::pair<std::string, std::string>> texts;
  {
    py::gil_scoped_release release;
    const SymbolicReferenceDynamics g = generate_symbolic(problem, opt);
    if (c) {
      texts.emplace_back("c_header", g.c_header());
      texts.emplace_back("c_source", g.c_source());
    }
    if (latex) texts.emplace_back("latex", g.latex());
    if (json) texts.emplace_back("json", g.json());
  }
  py::dict d;
  for (const auto& [k, v] : texts) d[py::str(k)] = v;
  return d;
}

// ---------------------------------------------------------------- variants
py::dict run_variants(const std::string& source, bool is_text, const std::string& source_name, bool track, int jobs,
                      const std::string& dir, const py::object& progress) {
  if (jobs < 0) throw Error("jobs: expected 0 (every core) or a number of threads >= 1, got " + std::to_string(jobs));
  ScenarioSpec spec;
  std::unique_ptr<Problem> base;
  std::vector<io::Variant> variants;
  std::vector<io::VariantSummary> summaries;
  double wall = 0;
  // progress(done, total, name), called with the GIL held; an exception it raises is kept
  // (the remaining calls are skipped) and raised again after the run. Python objects are
  // created and dropped only with the GIL held.
  io::VariantOptions vo;
  auto callback = std::make_shared<py::object>(progress);
  auto raised = std::make_shared<std::optional<py::error_already_set>>();
  if (!progress.is_none())
    vo.on_done = [callback, raised](size_t done, size_t total, const std::string& name) {
      py::gil_scoped_acquire gil;
      if (raised->has_value()) return;
      try {
        (*callback)(done, total, name);
      } catch (py::error_already_set& e) {
        raised->emplace(std::move(e));
      }
    };
  {
    py::gil_scoped_release release;
    spec = scenario_spec(source, is_text, source_name);
    base = build_problem(spec);  // validates the base scenario, as refdyn plan does
    variants = io::expand_variants(spec);
    if (variants.empty())
      throw Error(spec.file + ": variants: missing (run_variants needs a variants: section; see docs/sweeps.md)");
    if (track && base->experiments.empty())
      throw Error(spec.file + ": experiments: missing or an empty list (track needs at least one experiment; see "
                  "docs/scenario.md)");
    vo.track = track;
    vo.jobs = jobs;
    if (!dir.empty()) {
      io::prepare_output_dir(dir);
      vo.dir = dir;
    }
    const auto start = std::chrono::steady_clock::now();
    summaries = io::run_variants(spec, variants, vo);
    wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (raised->has_value()) {
    py::error_already_set e = std::move(**raised);
    raised->reset();
    throw e;
  }
  const bool tracked = track && !base->experiments.empty();
  const std::string csv = io::variants_csv(base->model.joint_name, variants, summaries, tracked);
  JsonValue summary = io::variants_summary_json(base->name, base->file, base->model.joint_name, variants, summaries,
                                                tracked, wall);
  if (!dir.empty()) {  // the aggregate as `refdyn plan/track` writes it (summary.json last)
    summary["variant_folders"] = true;
    io::write_text_atomic(std::filesystem::path(dir) / "variants.csv", csv);
    io::write_text_atomic(std::filesystem::path(dir) / "summary.json", json_text(summary, 2, 2) + "\n");
  }
  py::list vs;
  bool ok = true;
  for (size_t i = 0; i < variants.size(); ++i) {
    const io::VariantSummary& s = summaries[i];
    py::dict e;
    e["name"] = variants[i].name;
    py::dict values;
    for (const auto& [k, v] : variants[i].values) values[py::str(k)] = v;
    e["values"] = values;
    e["sample"] = variants[i].sample >= 0 ? py::object(py::int_(variants[i].sample)) : py::object(py::none());
    for (const auto& [k, v] : py_dict(s)) e[k] = v;
    if (!s.error.empty()) e["status"] = "invalid";
    e["ok"] = s.ok();
    ok = ok && s.ok();
    vs.append(e);
  }
  py::dict d;
  d["variants"] = vs;
  d["joints"] = base->model.joint_name;
  d["csv"] = csv;
  d["summary_json"] = json_text(summary, 2, 2);
  d["ok"] = ok;
  d["wall_time"] = wall;
  return d;
}

/// refdyn.Error (ValueError) and refdyn.NumericalFailure, translated from the C++ exceptions.
void bind_errors(py::module_& m) {
  static py::exception<Error> error(m, "Error", PyExc_ValueError);
  static py::exception<NumericalFailure> numerical(m, "NumericalFailure", error.ptr());
  // Translators registered later are tried first: the more specific one last.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const NumericalFailure& e) {
      numerical(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });
}

/// refdyn.Model: a compiled multibody model and its algorithms; models from URDF.
void bind_model(py::module_& m) {
  py::class_<PyModel, std::shared_ptr<PyModel>>(m, "Model",
      "A compiled multibody model with its own workspace. Functions take q, qd, ... as 1-D arrays of size nq "
      "and return new float64 arrays. Not thread-safe (one workspace); copy() for another.")
      .def_property_readonly("name", [](const PyModel& s) { return s.model->name; })
      .def_property_readonly("nq", [](const PyModel& s) { return s.model->nq; })
      .def_property_readonly("joint_names", [](const PyModel& s) { return s.model->joint_name; })
      .def_property_readonly("link_names", [](const PyModel& s) { return s.model->body_name; })
      .def_property_readonly("point_names", [](const PyModel& s) { return s.model->point_name; })
      .def_property_readonly("gravity", [](const PyModel& s) { return Vec(s.model->gravity); })
      .def_property_readonly("total_mass", [](const PyModel& s) { return s.model->total_mass(); })
      .def_property_readonly("limits", [](const PyModel& s) {
        py::dict d;
        for (int i = 0; i < s.model->nq; ++i) d[py::str(s.model->joint_name[i])] = limits_dict(s.model->limits[i]);
        return d;
      }, "Per joint: {lower, upper, velocity, effort} (inf: none).")
      .def("summary", [](const PyModel& s) { return s.model->summary(); })
      .def("copy", [](const PyModel& s) { return std::make_shared<PyModel>(*s.model); },
           "The same model (same id) with a workspace of its own.")
      .def("__repr__", [](const PyModel& s) {
        return "<refdyn.Model '" + s.model->name + "' nq=" + std::to_string(s.model->nq) + ">";
      })
      .def("mass_matrix", [](PyModel& s, const Arr& q) { return out(mass_matrix(*s.model, s.data, s.arg(0, q, "q"))); },
           py::arg("q"), "M(q), shape (nq, nq).")
      .def("bias_forces", [](PyModel& s, const Arr& q, const Arr& qd) {
             return out(bias_forces(*s.model, s.data, s.arg(0, q, "q"), s.arg(1, qd, "qd")));
           }, py::arg("q"), py::arg("qd"), "c(q, qd) + g(q), shape (nq,).")
      .def("gravity_forces", [](PyModel& s, const Arr& q) { return out(gravity_forces(*s.model, s.data, s.arg(0, q, "q"))); },
           py::arg("q"), "g(q), shape (nq,).")
      .def("inverse_dynamics", [](PyModel& s, const Arr& q, const Arr& qd, const Arr& qdd) {
             return out(inverse_dynamics(*s.model, s.data, s.arg(0, q, "q"), s.arg(1, qd, "qd"), s.arg(2, qdd, "qdd")));
           }, py::arg("q"), py::arg("qd"), py::arg("qdd"), "tau = M qdd + c + g (RNEA), shape (nq,).")
      .def("forward_dynamics", [](PyModel& s, const Arr& q, const Arr& qd, const Arr& tau) {
             return out(forward_dynamics(*s.model, s.data, s.arg(0, q, "q"), s.arg(1, qd, "qd"), s.arg(2, tau, "tau")));
           }, py::arg("q"), py::arg("qd"), py::arg("tau"), "qdd = M^-1 (tau - c - g), shape (nq,).")
      .def("kinetic_energy", [](PyModel& s, const Arr& q, const Arr& qd) {
             return kinetic_energy(*s.model, s.data, s.arg(0, q, "q"), s.arg(1, qd, "qd"));
           }, py::arg("q"), py::arg("qd"))
      .def("potential_energy", [](PyModel& s, const Arr& q) { return potential_energy(*s.model, s.data, s.arg(0, q, "q")); },
           py::arg("q"))
      .def("point_position", [](PyModel& s, const Arr& q, const std::string& point) {
             const int p = s.model->point_index(point);
             s.fk(q);
             return out(Vec(point_position(*s.model, s.data, p)));
           }, py::arg("q"), py::arg("point"), "World position of a named point, shape (3,).")
      .def("point_jacobian", [](PyModel& s, const Arr& q, const std::string& point) {
             const int p = s.model->point_index(point);
             s.fk(q);
             point_jacobian(*s.model, s.data, p);
             return out(s.data.Jp);
           }, py::arg("q"), py::arg("point"), "d r_P / d q in the world frame, shape (3, nq).")
      .def("point_velocity", [](PyModel& s, const Arr& q, const Arr& qd, const std::string& point) {
             const int p = s.model->point_index(point);
             s.fk(q);
             const PointDrift d = point_drift(*s.model, s.data, p, s.arg(1, qd, "qd"));
             return py::make_tuple(out(Vec(d.velocity)), out(Vec(d.drift)));
           }, py::arg("q"), py::arg("qd"), py::arg("point"),
           "(velocity C qd, drift d = r_P'' - C qdd) of a named point in the world frame.")
      .def("link_transform", [](PyModel& s, const Arr& q, const std::string& link) {
             const int b = s.model->body_index(link);
             s.fk(q);
             return out(link_transform(*s.model, s.data, b).matrix());
           }, py::arg("q"), py::arg("link"), "4x4 pose of a link's frame in the world.");

  m.def("model_from_urdf_file", [](const std::string& path, const std::string& root, bool points) {
        std::vector<io::UrdfMimic> mimics;  // couplings are constraints of a scenario, not part of a model
        return urdf_model(io::load_urdf(path, urdf_options(root, points), &mimics));
      }, py::arg("path"), py::arg("root_link") = "", py::arg("points_for_links") = true);
  m.def("model_from_urdf_string", [](const std::string& xml, const std::string& source, const std::string& root,
                                     bool points) {
        std::vector<io::UrdfMimic> mimics;
        return urdf_model(io::parse_urdf(xml, source, urdf_options(root, points), &mimics));
      }, py::arg("xml"), py::arg("source_name") = "<string>", py::arg("root_link") = "",
      py::arg("points_for_links") = true);
}

/// refdyn.Problem: a built scenario; load_problem, parse_problem.
void bind_problem(py::module_& m) {
  py::class_<Problem, std::shared_ptr<Problem>>(m, "Problem", "A built scenario (io::load_problem / parse_problem).")
      .def_readonly("file", &Problem::file)
      .def_readonly("name", &Problem::name)
      .def_readonly("parameters", &Problem::parameters)
      .def_property_readonly("model", [](const Problem& p) { return std::make_shared<PyModel>(p.model); },
                             "A copy of the problem's model (with a workspace of its own).")
      .def_property_readonly("joint_names", [](const Problem& p) { return p.model.joint_name; })
      .def_property_readonly("q0", [](const Problem& p) { return p.q0; })
      .def_property_readonly("qd0", [](const Problem& p) { return p.qd0; })
      .def_property_readonly("t0", [](const Problem& p) { return p.integrator.t0; })
      .def_property_readonly("t1", [](const Problem& p) { return p.integrator.t1; })
      .def_property_readonly("step", [](const Problem& p) { return p.integrator.step; })
      .def("_constraint_row_info", [](const Problem& p) {
        // Per row (refdyn.Problem.constraint_rows wraps these): its name, the constraint it
        // belongs to and its index there, order, origin, kind, time dependence, formula.
        py::list rows;
        for (int i = 0; i < p.constraints.rows(); ++i) {
          const int k = p.constraints.row_owner(i);
          const Constraint& c = *p.constraints.constraints()[k];
          const int order = c.order();
          py::dict d;
          d["name"] = p.constraints.row_name(i);
          d["constraint"] = c.name;
          d["index"] = i - p.constraints.row_offset(k);
          d["order"] = order;
          d["order_label"] = order_label(order);
          d["origin"] = to_string(c.origin);
          d["kind"] = order == 3 ? "jerk-level" : order == 2 ? "acceleration-level" : c.first_order() ? "first-order"
                                                                                                      : "holonomic";
          d["rheonomic"] = c.rheonomic();
          d["description"] = c.describe();
          rows.append(d);
        }
        return rows;
      })
      .def_property_readonly("experiments", [](const Problem& p) {
        std::vector<std::string> r;
        for (const auto& e : p.experiments) r.push_back(e->name);
        return r;
      })
      .def("constraints", [](const Problem& p, double t, const Vec& q, const Vec& qd) {
             p.model.check_q(q, "q");
             p.model.check_q(qd, "qd");
             Data data(p.model);
             ConstraintEval ev(p.model, p.constraints);
             evaluate_constraints(p.model, data, p.constraints, ev, t, q, qd);
             py::dict d;
             std::vector<std::string> rows;
             for (int i = 0; i < p.constraints.rows(); ++i) rows.push_back(p.constraints.row_name(i));
             d["rows"] = rows;
             d["phi"] = ev.phi;
             d["phid"] = ev.phid;
             d["A"] = ev.A;
             d["gamma"] = ev.gamma;
             return d;
           }, py::arg("t"), py::arg("q"), py::arg("qd"),
           "The constraint rows at (t, q, qd): {rows, phi (Phi or c), phid, A (m x n), gamma}.")
      .def("__repr__", [](const Problem& p) { return "<refdyn.Problem '" + p.name + "' from " + p.file + ">"; });

  m.def("load_problem", [](const std::string& path) {
        std::unique_ptr<Problem> p;
        {
          py::gil_scoped_release release;
          p = io::load_problem(path);
          check_optimize_of(io::load_scenario(path), *p);
        }
        return std::shared_ptr<Problem>(std::move(p));
      }, py::arg("path"));
  m.def("parse_problem", [](const std::string& yaml, const std::string& source) {
        std::unique_ptr<Problem> p;
        {
          py::gil_scoped_release release;
          p = io::parse_problem(yaml, source);
          check_optimize_of(io::parse_scenario(yaml, source), *p);
        }
        return std::shared_ptr<Problem>(std::move(p));
      }, py::arg("yaml"), py::arg("source_name") = "<string>");
}

/// refdyn.Results: what a run recorded, as arrays and dicts.
void bind_results(py::module_& m) {
  py::class_<PyResults, std::shared_ptr<PyResults>>(m, "Results")
      .def_property_readonly("ok", [](const PyResults& r) { return r.results.ok(); })
      .def_property_readonly("wall_time", [](const PyResults& r) { return r.results.wall_time; })
      .def_property_readonly("plan_table", [](const PyResults& r) { return table_of(r.results.plan); })
      .def_property_readonly("plan_summary", [](const PyResults& r) { return summary_of(r.results.plan.summary); })
      .def_property_readonly("plan_layout", [](const PyResults& r) { return layout_of(r.results.plan); })
      .def_property_readonly("run_names", [](const PyResults& r) {
        std::vector<std::string> n;
        for (const auto& run : r.results.runs) n.push_back(run.experiment->name);
        return n;
      })
      .def("run_table", [](const PyResults& r, size_t i) { return table_of(r.results.runs.at(i).result); })
      .def("run_summary", [](const PyResults& r, size_t i) {
        // The run's integration summary and its metrics (RunSummary's fields: saturated
        // samples, final and peak values, per joint e0, settle time, late error, peak |tau|).
        const io::RunRecord& run = r.results.runs.at(i);
        py::dict d = summary_of(run.result.summary);
        for (const auto& [k, v] : py_dict(run.summary)) d[k] = v;
        return d;
      })
      .def("run_layout", [](const PyResults& r, size_t i) { return layout_of(r.results.runs.at(i).result); })
      .def_property_readonly("feasibility_json", [](const PyResults& r) { return r.results.feasibility.json(); })
      .def_property_readonly("feasibility_text", [](const PyResults& r) { return r.results.feasibility.text(); })
      .def_property_readonly("feasible", [](const PyResults& r) { return r.results.feasibility.feasible(); })
      .def_property_readonly("summary_json", [](const PyResults& r) {
        return json_text(io::summary_json(*r.problem, r.results), 0);
      })
      .def("write", [](const PyResults& r, const std::string& dir) {
        io::write_results(dir, *r.problem, r.results, io::summary_json(*r.problem, r.results));
      }, py::arg("dir"), "Writes plan.csv, feasibility.json, sweep.csv, summary.json, track_<name>.csv as the CLI does.");
}

/// check, generate, run_variants, optimize: the command-line tools as functions.
void bind_tools(py::module_& m) {
  m.def("check", [](const std::string& source, bool is_text, const std::string& source_name) {
        io::CheckReport r;
        {
          py::gil_scoped_release release;
          const ScenarioSpec spec = scenario_spec(source, is_text, source_name);
          r = io::check_scenario(spec, is_text ? source_name : source);
        }
        return check_dict(r);
      }, py::arg("source"), py::arg("is_text"), py::arg("source_name") = "<string>",
      "io::check_scenario of a file (is_text false) or YAML text: what `refdyn check` prints, as a dict.");
  m.def("generate", [](const std::shared_ptr<Problem>& p, bool c, bool latex, bool json, const std::string& prefix) {
        return generate(*p, c, latex, json, prefix);
      }, py::arg("problem"), py::arg("c"), py::arg("latex"), py::arg("json"), py::arg("prefix") = "",
      "generate_symbolic without the GIL: {c_header, c_source, latex, json} (the formats asked for).");
  m.def("run_variants", &run_variants, py::arg("source"), py::arg("is_text"), py::arg("source_name"),
        py::arg("track"), py::arg("jobs"), py::arg("dir"), py::arg("progress"),
        "io::run_variants without the GIL: per variant its summary; variants.csv and summary.json as texts "
        "(and in dir, with a folder per variant, when dir is not empty).");
  m.def("optimize", [](const std::string& source, bool is_text, const std::string& source_name, const std::string& method,
                       long budget) {
        OptimizeResult r;
        {
          py::gil_scoped_release release;
          const ScenarioSpec spec = scenario_spec(source, is_text, source_name);
          OptimizeOptions o;
          o.method = method;
          o.budget = budget;
          r = optimize_scenario(spec, o);
        }
        const OptimizeSummary& s = r.summary;
        py::dict d;
        d["method"] = s.method;
        d["status"] = s.status;
        d["message"] = s.message;
        d["evaluations"] = s.evaluations;
        d["feasible"] = s.feasible;
        d["objective"] = s.best_objective;
        d["wall_time"] = s.wall_time;
        py::dict best;
        for (size_t i = 0; i < s.variables.size(); ++i) best[py::str(s.variables[i])] = s.best_x[i];
        d["best"] = best;
        d["variables"] = s.variables;
        d["constraint_names"] = s.constraint_names;
        const auto n = static_cast<py::ssize_t>(s.history.size());
        const auto nv = static_cast<py::ssize_t>(s.variables.size()), nc = static_cast<py::ssize_t>(s.constraint_names.size());
        py::array_t<double> x({n, nv}), obj(n), g({n, nc});
        py::array_t<bool> feas(n), ok(n);
        py::list reasons;
        auto X = x.mutable_unchecked<2>();
        auto O = obj.mutable_unchecked<1>();
        auto G = g.mutable_unchecked<2>();
        auto F = feas.mutable_unchecked<1>();
        auto K = ok.mutable_unchecked<1>();
        for (py::ssize_t i = 0; i < n; ++i) {
          const OptimizeEvaluation& e = s.history[static_cast<size_t>(i)];
          for (py::ssize_t k = 0; k < nv; ++k) X(i, k) = e.x[static_cast<size_t>(k)];
          for (py::ssize_t k = 0; k < nc; ++k) G(i, k) = e.constraints[static_cast<size_t>(k)];
          O(i) = e.objective;
          F(i) = e.feasible;
          K(i) = e.ok;
          reasons.append(e.reason);
        }
        py::dict h;
        h["x"] = x;
        h["objective"] = obj;
        h["constraints"] = g;
        h["feasible"] = feas;
        h["ok"] = ok;
        h["reason"] = reasons;
        d["history"] = h;
        d["csv"] = optimization_csv(s);
        return d;
      }, py::arg("source"), py::arg("is_text"), py::arg("source_name"), py::arg("method"), py::arg("budget"),
      "optimize_scenario without the GIL: the summary as a dict, the history as NumPy arrays.");
}

/// sensitivity and run: planning and tracking without the GIL.
void bind_runs(py::module_& m) {
  m.def("sensitivity", [](const std::shared_ptr<Problem>& p, const std::vector<std::string>& parameters) {
        SensitivityOptions o;
        o.parameters = parameters;
        Plan plan;
        PlanSensitivity s;
        std::vector<Metric> metrics;
        Eigen::MatrixXd G;
        {
          py::gil_scoped_release release;
          check_sensitivity_request(*p, o);
          plan = plan_problem(*p, *p->make_planner());
          if (!plan.summary.ok()) throw Error("no sensitivities: the plan stopped early: " + plan.summary.message);
          s = plan_sensitivity(*p, plan, o);
          metrics = plan_metrics(p->model, plan, p->residual_from);
          G = metric_gradients(*p, plan, s, metrics);
        }
        const auto K = static_cast<py::ssize_t>(s.t.size()), np = static_cast<py::ssize_t>(parameters.size());
        auto stack = [&](const std::vector<Eigen::MatrixXd>& v) {  // samples x rows x parameters
          const auto rows = v.empty() ? py::ssize_t{0} : static_cast<py::ssize_t>(v[0].rows());
          py::array_t<double> a({K, rows, np});
          auto A = a.mutable_unchecked<3>();
          for (py::ssize_t k = 0; k < K; ++k)
            for (py::ssize_t i = 0; i < rows; ++i)
              for (py::ssize_t j = 0; j < np; ++j) A(k, i, j) = v[static_cast<size_t>(k)](i, j);
          return a;
        };
        py::dict d;
        d["parameters"] = parameters;
        d["t"] = out(Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(s.t.data(), static_cast<Eigen::Index>(s.t.size()))));
        d["dx"] = stack(s.dx);
        d["dqdd"] = stack(s.dqdd);
        d["deffort"] = stack(s.deffort);
        d["dphi"] = stack(s.dphi);
        d["dt_end"] = out(Eigen::VectorXd(s.dt_end.transpose()));
        py::dict ms;
        for (size_t i = 0; i < metrics.size(); ++i) {
          py::dict e;
          e["value"] = metrics[i].value;
          e["t"] = metrics[i].sample >= 0 ? py::object(py::float_(s.t[static_cast<size_t>(metrics[i].sample)])) : py::none();
          e["gradient"] = out(Eigen::VectorXd(G.row(static_cast<Eigen::Index>(i)).transpose()));
          ms[py::str(metrics[i].name)] = e;
        }
        d["metrics"] = ms;
        d["wall_time"] = s.seconds;
        return d;
      }, py::arg("problem"), py::arg("parameters"),
      "plan_problem + plan_sensitivity + metric_gradients without the GIL (docs/sensitivity.md).");
  m.def("run", [](const std::shared_ptr<Problem>& p, bool track, const py::object& progress, int jobs) {
        return run(p, track, progress, jobs);
      }, py::arg("problem"), py::arg("track") = false, py::arg("progress") = py::none(), py::arg("jobs") = 1,
      "io::run_problem without the GIL. progress: None or callable(what, t, t0, t1); jobs: threads for the "
      "experiments (0: every core; the results do not depend on it).");
}

}  // namespace

// Each bind_* above is one area of the module (as Pinocchio's expose-*.cpp files are). They stay
// in one translation unit: pybind11's headers cost ~20 CPU-seconds per file to compile.
PYBIND11_MODULE(_refdyn, m) {
  m.doc() = "refdyn: task-based motion planning from reference dynamics (compiled part)";

  bind_errors(m);
  bind_model(m);
  bind_problem(m);
  bind_results(m);
  bind_tools(m);
  bind_runs(m);
}
