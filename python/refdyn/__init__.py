"""refdyn: task-based motion planning from reference dynamics, from Python.

    import refdyn
    problem = refdyn.load("examples/paper/paper.yaml")     # a file, YAML text or a dict
    plan = refdyn.plan(problem)                             # a Trajectory (NumPy arrays)
    plan["psi1"], plan.q, plan.t                            # columns by name, typed views
    result = refdyn.track(problem)                          # plan + closed-loop runs + feasibility
    model = problem.model                                   # FK, Jacobian, M, c + g, ID, FD
    refdyn.check("examples/paper/paper.yaml")               # what `refdyn check` prints, as a dict
    refdyn.generate(problem, formats="c")                   # the generated C (and LaTeX, JSON) texts
    refdyn.run_variants("examples/planar_2r_circle/family.yaml")  # variants: per-variant summaries

Errors in the input raise refdyn.Error (a ValueError) with the one-line message of the C++
library ("file:line: key: ..."). A run that stops (a numerical outcome) is not an exception:
see Trajectory.ok / .status / .message. See docs/python.md.
"""
from __future__ import annotations

import json as _json
import os as _os
import sys as _sys
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Union

import numpy as np

from ._refdyn import Error, Model, NumericalFailure, Problem  # noqa: F401
from . import _refdyn

for _cls in (Error, NumericalFailure, Model, Problem):
    _cls.__module__ = "refdyn"  # refdyn.Error in tracebacks, not refdyn._refdyn.Error

__all__ = [
    "Error", "NumericalFailure", "Model", "Problem", "Trajectory", "TrackResult", "Results",
    "load", "loads", "from_dict", "plan", "track", "run", "model", "load_urdf", "parse_urdf",
    "ConstraintRow", "check", "generate", "run_variants", "VariantResults", "optimize", "sensitivity",
]
__version__ = "0.2.0"  # = project(VERSION) in CMakeLists.txt (cli_test checks)

# --------------------------------------------------------------------------- scenarios

def load(source: Union[str, "_os.PathLike[str]", dict, Problem]) -> Problem:
    """A built scenario from a file path, YAML text (a str with a newline) or a dict."""
    if isinstance(source, Problem):
        return source
    if isinstance(source, dict):
        return from_dict(source)
    if isinstance(source, str) and "\n" in source:
        return loads(source)
    if isinstance(source, (str, _os.PathLike)):
        return _refdyn.load_problem(_os.fspath(source))
    raise TypeError(f"refdyn.load: expected a path, YAML text or a dict, got {type(source).__name__}")


def loads(yaml_text: str, source_name: str = "<string>") -> Problem:
    """A built scenario from YAML text. `source_name` names it in messages and anchors relative
    paths (e.g. a URDF file): pass a path such as "dir/scenario.yaml" to resolve them from dir."""
    return _refdyn.parse_problem(yaml_text, source_name)


def _plain(x: Any) -> Any:
    """Dict/list/scalars with NumPy values turned into plain Python (for JSON)."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    return x


def _dict_text(d: dict) -> str:
    # JSON is YAML: floats are written with repr (round-trip exact); one key per line, so that
    # a message's line number points into this text (refdyn.scenario_text(d) shows it).
    return _json.dumps(_plain(d), indent=1)


def scenario_text(d: dict) -> str:
    """The YAML (JSON) text that from_dict parses; error line numbers refer to it."""
    return _dict_text(d)


def from_dict(d: dict, source_name: str = "<dict>") -> Problem:
    """A built scenario from a dict with the keys of a scenario file (docs/scenario.md).
    Numbers may be expressions in strings ("90*deg"); NumPy arrays are accepted for lists."""
    return _refdyn.parse_problem(_dict_text(d), source_name)


def _scenario_source(source, what: str, source_name: Optional[str] = None):
    """(text or path, is_text, source name) of a path, YAML text or a dict (as load() takes them);
    source_name names a text or dict (as loads' does), default "<string>" / "<dict>"."""
    if isinstance(source, dict):
        return _dict_text(source), True, source_name or "<dict>"
    if isinstance(source, str) and "\n" in source:
        return source, True, source_name or "<string>"
    if isinstance(source, (str, _os.PathLike)):
        return _os.fspath(source), False, ""
    raise TypeError(f"refdyn.{what}: expected a path, YAML text or a dict, got {type(source).__name__}")


class ConstraintRow(str):
    """One row of a problem's constraints (Problem.constraint_rows). It is the row's name, a str
    ("ellipse", "loop[1]"), as the list held before, with what the row is:
    constraint (the constraint's name), index (its row within the constraint), order (0 position,
    1 velocity, 2 acceleration, 3 jerk), order_label ("holonomic (position)", ...), origin
    ("material" or "programmed"), kind ("holonomic", "first-order", "acceleration-level",
    "jerk-level"), rheonomic (explicitly time-dependent) and description (the formula)."""

    _FIELDS = ("constraint", "index", "order", "order_label", "origin", "kind", "rheonomic", "description")

    def __new__(cls, info: dict):
        row = super().__new__(cls, info["name"])
        for k in cls._FIELDS:
            setattr(row, k, info[k])
        return row

    @property
    def name(self) -> str:
        return str(self)

    def as_dict(self) -> Dict[str, Any]:
        return {"name": str(self), **{k: getattr(self, k) for k in self._FIELDS}}

    def __repr__(self) -> str:
        return (f"ConstraintRow({str(self)!r}, order={self.order}, origin={self.origin!r}, kind={self.kind!r}, "
                f"rheonomic={self.rheonomic})")


def _constraint_rows(problem: Problem) -> list:
    return [ConstraintRow(info) for info in problem._constraint_row_info()]


Problem.constraint_rows = property(
    _constraint_rows,
    doc="The constraint rows in order, each a ConstraintRow: its name (a str) with its order, origin, kind, ...")


def check(source: Union[str, "_os.PathLike[str]", dict], source_name: Optional[str] = None) -> Dict[str, Any]:
    """What `refdyn check` prints, as a dict: scenario, file, model (text), joints, constraints (name,
    origin, kind, order, order_label, rheonomic, rows, description), rows (total, material, programmed,
    holonomic, first_order, acceleration, jerk), force_elements, planner, t0, initial_acceleration
    (None or {values, source}), partition (None or {independent, dependent, automatic, condition}),
    projection (None or per moved joint {dq, q, dqd, qd}), residuals (per row {label: value}),
    integrator, experiments, variants (names) and text (the command's output, the same bytes).
    source: a path, YAML text or a dict (source_name names a text or dict in messages and anchors
    its relative paths, as in loads). An invalid scenario raises refdyn.Error with the command's
    message."""
    text, is_text, name = _scenario_source(source, "check", source_name)
    return _refdyn.check(text, is_text, name)


_FORMATS = ("c", "latex", "json")


def generate(source, formats: Union[str, tuple, list] = _FORMATS, prefix: str = "") -> Dict[str, str]:
    """The generated reference dynamics (`refdyn generate`) as texts: {"c_header", "c_source"} for
    "c", "latex", "json", for the formats asked for (a comma-separated str such as "c,latex" or a
    list). prefix: the C identifiers' prefix (default: "rd_" + the scenario's name). source: a
    path, YAML text, a dict or a Problem. The GIL is released while generating."""
    if isinstance(formats, str):
        wanted = [f for f in formats.split(",")]
    elif isinstance(formats, (list, tuple)):
        wanted = list(formats)
    else:
        raise TypeError(f"refdyn.generate: formats: expected a str or a list, got {type(formats).__name__}")
    for f in wanted:
        if f not in _FORMATS:
            raise Error(f"formats: expected a comma-separated list of c, latex, json, got '{f}'")
    if not wanted:
        raise Error("formats: expected at least one of c, latex, json")
    return _refdyn.generate(load(source), "c" in wanted, "latex" in wanted, "json" in wanted, prefix)


@dataclass(frozen=True)
class VariantResults:
    """A family of variants run (refdyn.run_variants): per variant a dict (name, values of the varied
    parameters, sample, error, status, message, t_end, max_constraint_residual, feasible, violations,
    peak_speed, peak_effort per joint, runs, runs_completed, worst_final_error, worst_peak_tau,
    wall_time, ok), the joints, variants.csv and summary.json (a dict) as `refdyn plan/track` write
    them, ok (every variant complete) and the wall time."""
    variants: list
    joints: tuple
    csv: str
    summary: Dict[str, Any]
    ok: bool
    wall_time: float

    def __getitem__(self, name: str) -> Dict[str, Any]:
        for v in self.variants:
            if v["name"] == name:
                return v
        raise KeyError(f"no variant '{name}' (variants: {', '.join(v['name'] for v in self.variants)})")

    def __len__(self) -> int:
        return len(self.variants)

    def column(self, key: str) -> np.ndarray:
        """One number per variant (t_end, feasible, ...) as an array, in the variants' order."""
        return np.array([v[key] for v in self.variants])


def run_variants(source, track: bool = False, jobs: int = 1, directory: Union[str, "_os.PathLike[str]", None] = None,
                 progress: Optional[Callable] = None, source_name: Optional[str] = None) -> VariantResults:
    """Plans (track=True: and tracks) every variant of a scenario's `variants:` section, on `jobs`
    threads (0: every core; the results do not depend on it), without the GIL. directory: also
    write what `refdyn plan/track` writes there (a folder per variant, variants.csv,
    summary.json). progress: None or callable(done, total, name) after each variant. A variant
    that is not a valid scenario or stops early is a result (its error/status), not an
    exception; an invalid base scenario or variants section raises refdyn.Error. source_name: as
    in check."""
    text, is_text, name = _scenario_source(source, "run_variants", source_name)
    if progress is not None and not callable(progress):
        raise TypeError("refdyn.run_variants: progress: expected None or a callable(done, total, name)")
    r = _refdyn.run_variants(text, is_text, name, track, jobs, _os.fspath(directory) if directory else "", progress)
    return VariantResults(variants=r["variants"], joints=tuple(r["joints"]), csv=r["csv"],
                          summary=_json.loads(r["summary_json"]), ok=r["ok"], wall_time=r["wall_time"])


def optimize(source, method: Optional[str] = None, budget: Optional[int] = None,
             source_name: Optional[str] = None) -> Dict[str, Any]:
    """`refdyn optimize` of a scenario with an `optimize:` section (docs/optimize.md), without the
    GIL: {"method", "status", "message", "evaluations", "feasible", "objective", "best" (variable ->
    value), "variables", "constraint_names", "wall_time", "csv" (optimization.csv's text), "history":
    {"x" (evaluations x variables), "objective", "constraints" (evaluations x constraints, g <= 0),
    "feasible", "ok" (NumPy arrays), "reason" (list)}}. method / budget override the section's.
    A bad section raises refdyn.Error with the command's message. source: as in check."""
    text, is_text, name = _scenario_source(source, "optimize", source_name)
    if budget is not None and (not isinstance(budget, int) or budget <= 0):
        raise ValueError(f"refdyn.optimize: budget: expected a whole number > 0, got {budget!r}")
    return _refdyn.optimize(text, is_text, name, method or "", int(budget or 0))


def sensitivity(source, parameters) -> Dict[str, Any]:
    """The plan's forward sensitivities to scenario parameters (docs/sensitivity.md), as
    `refdyn plan --sensitivity` writes them: {"parameters", "t" (samples), "dx" (samples x state x
    parameters: d[q; qd; z]/dp), "dqdd", "deffort" (the actuator effort), "dphi" (constraint
    rows) likewise, "dt_end", "metrics": {name: {"value", "t", "gradient" (one per parameter)}},
    "wall_time"}, NumPy arrays. source: a Problem, or as load() takes it; parameters: a name or
    a list of names. A bad name raises refdyn.Error ("did you mean")."""
    problem = source if isinstance(source, Problem) else load(source)
    names = [parameters] if isinstance(parameters, str) else list(parameters)
    return _refdyn.sensitivity(problem, names)


# --------------------------------------------------------------------------- models

def model(section: Union[dict, str], parameters: Optional[dict] = None, source_name: str = "<model>") -> Model:
    """A Model from a scenario's `model:` section (dh, links or urdf; points, gravity, base),
    as a dict or YAML text, with optional parameters for its expressions."""
    if isinstance(section, str):
        try:
            import yaml  # python3-yaml
        except ImportError as e:  # pragma: no cover
            raise TypeError("refdyn.model: pass a dict (YAML text needs python3-yaml)") from e
        section = yaml.safe_load(section)
    if not isinstance(section, dict):
        raise TypeError(f"refdyn.model: expected a dict, got {type(section).__name__}")
    n = _count_coordinates(section, source_name)
    scenario = {"name": section.get("name", "model"), "model": section,
                "initial": {"q": [0] * n}, "integrator": {"t1": 1e-3}}
    if parameters:
        scenario = {"parameters": dict(parameters), **scenario}
    return _refdyn.parse_problem(_dict_text(scenario), source_name).model


def _count_coordinates(section: dict, source_name: str) -> int:
    def movable(entries, what):
        if not isinstance(entries, list):
            raise Error(f"{source_name}: model.{what}: expected a list of joints")
        return sum(1 for e in entries if not (isinstance(e, dict) and str(e.get("type", "revolute")) == "fixed"))
    if "dh" in section:
        dh = section["dh"]
        return movable(dh.get("joints") if isinstance(dh, dict) else dh, "dh.joints")
    if "links" in section:
        return movable(section["links"], "links")
    if "urdf" in section:
        u = section["urdf"]
        path = u.get("file") if isinstance(u, dict) else u
        if not isinstance(path, str):
            raise Error(f"{source_name}: model.urdf.file: expected a file name")
        base = _os.path.dirname(source_name) if source_name and not source_name.startswith("<") else ""
        root = u.get("root", "") if isinstance(u, dict) else ""
        return load_urdf(_os.path.join(base, path), root_link=root).nq
    return 0  # build_problem reports what is missing


def load_urdf(path: Union[str, "_os.PathLike[str]"], root_link: str = "", points_for_links: bool = True) -> Model:
    """A Model from a URDF file (urdfdom). <mimic> couplings are constraints, not part of a
    model: use a scenario file (model: {urdf: ...}) to get them."""
    return _refdyn.model_from_urdf_file(_os.fspath(path), root_link, points_for_links)


def parse_urdf(xml: str, source_name: str = "<string>", root_link: str = "", points_for_links: bool = True) -> Model:
    """A Model from URDF text."""
    return _refdyn.model_from_urdf_string(xml, source_name, root_link, points_for_links)


# --------------------------------------------------------------------------- trajectories

@dataclass(frozen=True, eq=False)  # eq: arrays have no single truth value
class Trajectory:
    """A recorded motion: `data` (float64, shape (samples, columns)) with named `columns`, the
    columns of refdyn's CSV files (t, q_*, qd_*, qdd_*, qref_*, e_*, tau_*, states, <point>_x|y|z,
    targets, phi_*, phid_*, force signals, Qc_*, required_*, reaction_*, lambda_*). A column by
    name: traj["q_psi1"] (or traj["psi1"] for q). Typed views: t, q, qd, qdd, q_ref, tau, point(P).
    The run's status: ok, status, message, t_end, steps, wall_time, max_constraint_residual."""
    name: str
    columns: tuple
    data: np.ndarray
    joints: tuple
    points: tuple
    summary: Dict[str, Any] = field(default_factory=dict)
    layout: Dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def _make(cls, name, table, summary, layout):
        header, data = table
        data.setflags(write=False)
        return cls(name=name, columns=tuple(header), data=data, joints=tuple(layout["joints"]),
                   points=tuple(layout["points"]), summary=summary, layout=layout)

    # --- columns
    def index(self, column: str) -> int:
        try:
            return self.columns.index(column)
        except ValueError:
            if "q_" + column in self.columns:
                return self.columns.index("q_" + column)
            raise KeyError(f"{self.name}: no column '{column}' (columns: {', '.join(self.columns)})") from None

    def __getitem__(self, column: str) -> np.ndarray:
        return self.data[:, self.index(column)]

    def __contains__(self, column: str) -> bool:
        return column in self.columns

    def __len__(self) -> int:
        return self.data.shape[0]

    def group(self, prefix: str) -> np.ndarray:
        """Columns prefix + joint for every joint, shape (samples, nq); e.g. group("tau_")."""
        return self.data[:, [self.index(prefix + j) for j in self.joints]]

    def point(self, name: str) -> np.ndarray:
        """World positions of a recorded point, shape (samples, 3)."""
        return self.data[:, [self.index(f"{name}_{c}") for c in "xyz"]]

    def as_dict(self) -> Dict[str, np.ndarray]:
        return {c: self.data[:, i] for i, c in enumerate(self.columns)}

    @property
    def t(self) -> np.ndarray:
        return self.data[:, 0]

    @property
    def q(self) -> np.ndarray:
        return self.group("q_")

    @property
    def qd(self) -> np.ndarray:
        return self.group("qd_")

    @property
    def qdd(self) -> np.ndarray:
        return self.group("qdd_")

    @property
    def q_ref(self) -> np.ndarray:
        return self.group("qref_")

    @property
    def tau(self) -> np.ndarray:
        return self.group("tau_")

    # --- status
    @property
    def ok(self) -> bool:
        return bool(self.summary.get("ok", True))

    @property
    def status(self) -> str:
        return self.summary.get("status", "")

    @property
    def message(self) -> str:
        return self.summary.get("message", "")

    def __repr__(self) -> str:
        return (f"Trajectory({self.name!r}, {self.data.shape[0]} samples x {self.data.shape[1]} columns, "
                f"status={self.status!r})")


@dataclass(frozen=True, eq=False)  # eq: arrays have no single truth value
class Results:
    """Everything one run of a scenario gives: the plan, the closed-loop runs (by experiment
    name; empty unless tracked), the feasibility report and summary.json as dicts."""
    problem: Problem
    plan: Trajectory
    runs: Dict[str, Trajectory]
    feasibility: Dict[str, Any]
    summary: Dict[str, Any]
    ok: bool
    wall_time: float
    _native: Any = field(repr=False, default=None)

    def write(self, directory: Union[str, "_os.PathLike[str]"]) -> None:
        """Writes plan.csv, feasibility.json, summary.json and track_<name>.csv (as the CLI)."""
        self._native.write(_os.fspath(directory))

    @property
    def feasibility_text(self) -> str:
        return self._native.feasibility_text


TrackResult = Results


def _progress(progress):
    if progress is None or progress is False:
        return None
    if callable(progress):
        return progress
    state = {}

    def bar(what, t, t0, t1):
        frac = 1.0 if t1 <= t0 else min(1.0, max(0.0, (t - t0) / (t1 - t0)))
        filled = int(30 * frac)
        _sys.stderr.write(f"\r{what:<32.32} [{'#' * filled}{'.' * (30 - filled)}] {100 * frac:5.1f}%")
        if frac >= 1.0 and not state.get(what):
            state[what] = True
            _sys.stderr.write("\n")
        _sys.stderr.flush()
    return bar


def run(scenario, track: bool = False, progress: Union[bool, Callable, None] = False, jobs: int = 1) -> Results:
    """Plans the scenario (and with track=True runs its experiments); the GIL is released
    during the run. progress: False (default), True (a bar on stderr) or callable(what, t, t0, t1)
    (for the plan, and for the run when there is one). jobs: threads running the experiments
    (0: every core); the results are the same bits for any number (docs/sweeps.md)."""
    problem = load(scenario)
    r = _refdyn.run(problem, track, _progress(progress), jobs)
    plan_ = Trajectory._make("plan", r.plan_table, r.plan_summary, r.plan_layout)
    runs = {name: Trajectory._make(name, r.run_table(i), r.run_summary(i), r.run_layout(i))
            for i, name in enumerate(r.run_names)}
    return Results(problem=problem, plan=plan_, runs=runs, feasibility=_json.loads(r.feasibility_json),
                   summary=_json.loads(r.summary_json), ok=r.ok, wall_time=r.wall_time, _native=r)


def plan(scenario, progress: Union[bool, Callable, None] = False) -> Trajectory:
    """The planned reference motion of a scenario (file, YAML text, dict or Problem)."""
    return run(scenario, track=False, progress=progress).plan


def track(scenario, progress: Union[bool, Callable, None] = False, jobs: int = 1) -> Results:
    """Plan + every closed-loop experiment (on `jobs` threads, 0: every core): Results with
    .plan, .runs[name], .feasibility, .summary (with "statistics" over the runs)."""
    return run(scenario, track=True, progress=progress, jobs=jobs)


def feasibility(scenario) -> Dict[str, Any]:
    """The feasibility report of the planned motion as a dict (feasibility.json)."""
    return run(scenario).feasibility
