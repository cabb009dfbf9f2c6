#!/usr/bin/env python3
"""Turn the output folder of `refdyn paper` into publication figures (PNG 200 dpi + PDF).

Usage:  /usr/bin/python3 scripts/plot_study.py RESULTS_DIR

Reads RESULTS_DIR/plan.csv, RESULTS_DIR/track_<label>.csv and (optionally)
RESULTS_DIR/summary.json, and writes RESULTS_DIR/figures/<name>.png and <name>.pdf:

  fig4_drive                 drive displacement psi_dr, planned psi1, drive twist, drive torque
  fig5_end_effector          (a) E in the x-y plane with the ellipse, (b) z_E(t) against z_a(t)
  fig6_joints                psi1, psi2, z3 of the frictionless closed-loop runs
  fig7_errors                |q - q_ref| of the perturbed frictionless runs, linear scale
  fig7_errors_log            the same on a log scale (zeros clipped to 1e-16)
  fig8_torques               tau1, tau2, F3 of the frictionless runs
  fig8_torques_first_second  the same for 0 <= t <= 1 s
  fig9_friction              runs on the plant with friction: errors (log) and torques
  fig10_plan                 the plan: constraint residuals, required joint efforts, Q_c

Every input file and column is checked before any figure is drawn; any bad input (a missing,
empty, binary, non-UTF-8 or malformed CSV, a missing column, a bad summary.json) ends the
program with one line "refdyn: error: FILE: message" on stderr and exit status 2 (warnings are
printed only when the figures were written). Figures are rendered to temporary files in
the figures folder and moved into place (os.replace) only after all of them rendered, so a
failure never leaves a half-written or mixed set of figures; their mode is 0666 minus the
umask, like the CSV files. The written paths are printed,
one per line.
"""

import glob
import json
import math
import os
import re
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

PROG = "plot_study.py"
DPI = 200
LOG_FLOOR = 1e-16         # floor for |.| on log axes (zeros cannot be drawn)
FRICTION_LOG_FLOOR = 1e-12  # fig9: only t = 0 and sign changes go below; saves 4 empty decades
NEGLIGIBLE = 1e-12        # a panel whose values all stay below this is labelled "round-off only"
REFERENCE_ALPHA = 45  # the plan starts from 45 deg; that run tracks it exactly
ZOOM_T1 = 1.0         # end of the zoom window of fig8_torques_first_second [s]

# Paper defaults (include/refdyn/models/paper_example.hpp), used only without summary.json.
DEFAULT_ELLIPSE = (0.5 * math.cos(math.pi / 4), 0.25)

JOINTS = ("psi1", "psi2", "z3")
Q_LABEL = {"psi1": r"$\psi_1$ [rad]", "psi2": r"$\psi_2$ [rad]", "z3": r"$z_3$ [m]"}
ERR_LABEL = {"psi1": r"$\Delta_1$ [rad]", "psi2": r"$\Delta_2$ [rad]", "z3": r"$\Delta_3$ [m]"}
ERR_SYMBOL = {"psi1": r"$\Delta_1$", "psi2": r"$\Delta_2$", "z3": r"$\Delta_3$"}
ERR_UNIT = {"psi1": "rad", "psi2": "rad", "z3": "m"}
TAU_LABEL = {"psi1": r"$\tau_1$ [N m]", "psi2": r"$\tau_2$ [N m]", "z3": r"$F_3$ [N]"}
EFFORT_UNIT = {"psi1": "N m", "psi2": "N m", "z3": "N"}
JOINT_NAME = {"psi1": r"joint 1 ($\psi_1$)", "psi2": r"joint 2 ($\psi_2$)",
              "z3": r"joint 3 ($z_3$)"}

# Okabe-Ito colours (colour-blind safe). Initial angles keep their colour in every figure;
# the 45 deg run is the reference and is always dashed black.
ANGLE_COLOUR = {60: "#0072B2", 70: "#009E73", 80: "#D55E00"}
EXTRA_COLOURS = ["#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000"]
PLAN_COLOUR = "#CC79A7"    # plan quantities that are not "the reference" (fig4, fig10)
PLAN_COLOUR2 = "#E69F00"
QC_COLOUR = "#56B4E9"
GUIDE_COLOUR = "0.6"       # ellipse, z_a(t): the geometric target drawn under the runs

PLAN_COLUMNS = (
    ["t"]
    + [f"q_{j}" for j in JOINTS] + [f"qd_{j}" for j in JOINTS] + [f"qdd_{j}" for j in JOINTS]
    + [f"z_{j}" for j in JOINTS]
    + ["E_x", "E_y", "E_z", "z_a", "phi_ellipse", "phi_height", "phid_ellipse", "phid_height",
       "psi_dr", "tau_drive"]
    + [f"Qc_{j}" for j in JOINTS] + [f"required_{j}" for j in JOINTS]
)
TRACK_COLUMNS = (
    ["t"]
    + [f"q_{j}" for j in JOINTS] + [f"qd_{j}" for j in JOINTS] + [f"qref_{j}" for j in JOINTS]
    + [f"e_{j}" for j in JOINTS] + [f"tau_{j}" for j in JOINTS]
    + ["E_x", "E_y", "E_z"]
)
LABEL_RE = re.compile(r"^a(\d+(?:\.\d+)?)_(nofriction|friction)$")

RC = {
    "font.size": 9,
    "axes.titlesize": 9.5,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "lines.linewidth": 1.2,
    "axes.grid": True,
    "grid.linewidth": 0.4,
    "grid.alpha": 0.5,
    "axes.xmargin": 0.0,
    "axes.formatter.use_mathtext": True,
    "axes.formatter.limits": (-3, 4),
    "legend.frameon": False,
    "figure.constrained_layout.use": True,
    "pdf.fonttype": 42,
    "ps.fonttype": 42,
    "savefig.bbox": "tight",
    "savefig.pad_inches": 0.04,
}


class InputError(Exception):
    """A missing or malformed input; reported as one line, exit status 2."""


WARNINGS = []


def one_line(msg):
    """The message with control characters (e.g. a newline in a folder name) escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(msg))


def warn(msg):
    """Collected, printed only on success (an error is exactly one line)."""
    WARNINGS.append(f"{PROG}: warning: {one_line(msg)}")


# ----------------------------------------------------------------------------- input

def parse_csv(path):
    """A numeric CSV with a header row: (columns, rows); InputError if it is not one."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, expected a CSV file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not raw.strip():
        raise InputError(f"{path}: empty file, expected a header row")
    if b"\0" in raw:
        raise InputError(f"{path}: binary data (NUL bytes), expected CSV text")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    lines = text.splitlines()
    cols = [c.strip() for c in lines[0].split(",")]
    rows = []
    for n, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        values = line.split(",")
        if len(values) != len(cols):
            raise InputError(f"{path}:{n}: {len(values)} values per row but {len(cols)} header "
                             "columns")
        try:
            rows.append([float(v) for v in values])
        except ValueError:
            bad = next(v for v in values if not _is_float(v))
            raise InputError(f"{path}:{n}: cannot parse numbers (not a number: "
                             f"{bad.strip()[:40]!r})") from None
    return cols, rows


def _is_float(v):
    try:
        float(v)
        return True
    except ValueError:
        return False


def read_csv(path, required):
    """Read a numeric CSV with a header row into {column: ndarray}, checking `required`."""
    cols, rows = parse_csv(path)
    missing = [c for c in required if c not in cols]
    if missing:
        what = "column" if len(missing) == 1 else f"{len(missing)} columns"
        shown = ", ".join(missing[:6]) + (f", ... (header: {','.join(cols)[:60]!r})"
                                          if len(missing) > 6 else "")
        raise InputError(f"{path}: missing {what} {shown}")
    if not rows:
        raise InputError(f"{path}: no data rows")
    data = np.array(rows, dtype=float)
    table = {c: data[:, i] for i, c in enumerate(cols)}
    bad = [c for c in required if not np.all(np.isfinite(table[c]))]
    if bad:
        warn(f"{path}: non-finite values in {', '.join(bad)} (drawn as gaps)")
        data[~np.isfinite(data)] = np.nan
    t = table["t"]
    if t.size > 1 and not np.all(np.diff(t) > 0):
        warn(f"{path}: column t is not strictly increasing")
    return table


class Run:
    def __init__(self, label, alpha, friction, data):
        self.label, self.alpha, self.friction, self.data = label, alpha, friction, data

    @property
    def is_reference(self):
        return abs(self.alpha - REFERENCE_ALPHA) < 1e-9


def enumerate_runs(results_dir, summary):
    """[(label, alpha_deg, friction)] from summary.json, else from track_*.csv names."""
    runs = []
    entries = summary.get("runs") if isinstance(summary, dict) else None
    if entries is not None and not isinstance(entries, list):
        raise InputError(f"{os.path.join(results_dir, 'summary.json')}: runs must be a list")
    if entries:
        for i, r in enumerate(entries):
            label = r.get("label") if isinstance(r, dict) else None
            if not label:
                raise InputError(f"{os.path.join(results_dir, 'summary.json')}: runs[{i}] "
                                 "has no label")
            m = LABEL_RE.match(label)
            if not isinstance(label, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+", label):
                raise InputError(f"{os.path.join(results_dir, 'summary.json')}: runs[{i}]: "
                                 f"label {one_line(label)[:40]!r} is not a plain name")
            m = LABEL_RE.match(label)
            alpha = r.get("alpha0_deg", float(m.group(1)) if m else None)
            friction = r.get("plant_friction", (m.group(2) == "friction") if m else None)
            if alpha is None or friction is None:
                raise InputError(f"{os.path.join(results_dir, 'summary.json')}: run {label}: "
                                 "missing alpha0_deg or plant_friction")
            if (isinstance(alpha, bool) or not isinstance(alpha, (int, float))
                    or not math.isfinite(alpha) or not isinstance(friction, bool)):
                raise InputError(f"{os.path.join(results_dir, 'summary.json')}: run {label}: "
                                 "alpha0_deg must be a number and plant_friction true/false")
            runs.append((label, float(alpha), friction))
        return runs
    for path in sorted(glob.glob(os.path.join(results_dir, "track_*.csv"))):
        label = os.path.basename(path)[len("track_"):-len(".csv")]
        m = LABEL_RE.match(label)
        if not m:
            warn(f"{path}: label not of the form a<deg>_(nofriction|friction), ignored")
            continue
        runs.append((label, float(m.group(1)), m.group(2) == "friction"))
    return runs


def load_inputs(results_dir):
    if not os.path.isdir(results_dir):
        raise InputError(f"{results_dir}: not a directory")
    summary = {}
    spath = os.path.join(results_dir, "summary.json")
    if os.path.isfile(spath):
        try:
            with open(spath, encoding="utf-8") as f:
                summary = json.load(f)
        except UnicodeDecodeError as exc:
            raise InputError(f"{spath}: not UTF-8 text (byte {exc.start})") from None
        except OSError as exc:
            raise InputError(f"{spath}: cannot read ({exc.strerror or exc})") from None
        except (ValueError, RecursionError) as exc:
            raise InputError(f"{spath}: not valid JSON ({one_line(exc)})") from None
        if not isinstance(summary, dict):
            raise InputError(f"{spath}: expected a JSON object at the top level")
    else:
        warn(f"{spath}: not found; runs taken from track_*.csv, paper ellipse half-axes")

    ellipse = DEFAULT_ELLIPSE
    if summary:
        e = summary.get("ellipse")
        if not isinstance(e, dict) or "a" not in e or "b" not in e:
            raise InputError(f"{spath}: missing key ellipse.a / ellipse.b")
        if not all(isinstance(e[k], (int, float)) and not isinstance(e[k], bool)
                   and math.isfinite(e[k]) and e[k] > 0 for k in ("a", "b")):
            raise InputError(f"{spath}: ellipse.a and ellipse.b must be positive numbers")
        ellipse = (float(e["a"]), float(e["b"]))

    plan = read_csv(os.path.join(results_dir, "plan.csv"), PLAN_COLUMNS)
    runs = []
    for label, alpha, friction in enumerate_runs(results_dir, summary):
        data = read_csv(os.path.join(results_dir, f"track_{label}.csv"), TRACK_COLUMNS)
        runs.append(Run(label, alpha, friction, data))
    runs.sort(key=lambda r: (r.friction, r.alpha))
    if not any(not r.friction for r in runs):
        raise InputError(f"{results_dir}: no frictionless run (track_a<deg>_nofriction.csv)")
    return plan, runs, ellipse


# ----------------------------------------------------------------------------- styling

def fmt_deg(alpha):
    return f"{alpha:g}"


def run_style(run):
    if run.is_reference:
        return dict(color="k", linestyle="--", linewidth=1.3, zorder=5,
                    label=rf"$\alpha_0$ = {fmt_deg(run.alpha)}° (reference)")
    colour = ANGLE_COLOUR.get(int(round(run.alpha)))
    if colour is None or abs(run.alpha - round(run.alpha)) > 1e-9:
        colour = EXTRA_COLOURS[int(round(run.alpha * 7)) % len(EXTRA_COLOURS)]
    return dict(color=colour, linestyle="-", linewidth=1.2, zorder=3,
                label=rf"$\alpha_0$ = {fmt_deg(run.alpha)}°")


def bottom_legend(fig, handles, ncol=None):
    """One legend for the whole figure, centred below the panels (never over data)."""
    ncol = ncol or min(len(handles), 4)
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=ncol,
               handlelength=2.6, columnspacing=1.6)


def run_handles(runs):
    return [Line2D([], [], **{k: v for k, v in run_style(r).items() if k != "zorder"})
            for r in runs]


def stacked(nrows, title, height=None, width=6.5):
    fig, axes = plt.subplots(nrows, 1, sharex=True, figsize=(width, height or 1.9 * nrows + 0.5))
    axes = np.atleast_1d(axes)
    fig.suptitle(title)
    axes[-1].set_xlabel(r"$t$ [s]")
    return fig, axes


def time_limits(ax, *ts):
    lo = min(float(np.nanmin(t)) for t in ts)
    hi = max(float(np.nanmax(t)) for t in ts)
    if hi > lo:
        ax.set_xlim(lo, hi)


def log_axis(ax, floor=LOG_FLOOR):
    """Log y axis spanning whole decades (so both ends carry a label); room below the floor
    only when some clipped value sits on it."""
    ax.set_yscale("log")
    ax.grid(True, which="major", linewidth=0.4, alpha=0.5)
    ax.grid(False, which="minor")
    ys = [np.asarray(l.get_ydata(), float) for l in ax.get_lines()]
    ys = np.concatenate([y[np.isfinite(y) & (y > 0)] for y in ys]) if ys else np.array([])
    if ys.size == 0:
        return
    lo, hi = float(ys.min()), float(ys.max())
    top = 10.0 ** math.ceil(math.log10(hi) - 1e-9)
    bottom = floor / 3.0 if lo <= floor else 10.0 ** math.floor(math.log10(lo) + 1e-9)
    if top <= bottom * 10.0:
        top = bottom * 100.0
    ax.set_ylim(bottom, top)


def pow10_text(x):
    return rf"$10^{{{int(round(math.log10(x)))}}}$"


def floor_text(floor=LOG_FLOOR):
    return pow10_text(floor)


def sci_text(x):
    """2.5e-19 -> '2.5·10⁻¹⁹' in mathtext."""
    if x == 0:
        return "0"
    e = int(math.floor(math.log10(abs(x))))
    m = x / 10.0 ** e
    return rf"${m:.2g}\cdot 10^{{{e}}}$"


def note_negligible(ax, values, symbol, unit, log=False, floor=LOG_FLOOR):
    """Say so in the panel when every run's value is exactly zero or only round-off."""
    peak = max((float(np.nanmax(v)) for v in values if v.size), default=0.0)
    if peak >= NEGLIGIBLE:
        return
    if peak == 0.0:
        text = f"{symbol} = 0 exactly in all runs"
    else:
        text = f"round-off only: max {symbol} = {sci_text(peak)} {unit}"
        if log and peak < floor:
            text += f" (below the floor {floor_text(floor)})"
    ax.text(0.5, 0.62, text, transform=ax.transAxes, ha="center", va="center", fontsize=8.5,
            bbox=dict(boxstyle="round,pad=0.3", facecolor="white", edgecolor="0.7",
                      linewidth=0.6))


# ----------------------------------------------------------------------------- figures

def fig4_drive(plan):
    t = plan["t"]
    fig, (a0, a1, a2) = stacked(3, "Flexible drive of joint 1 (plan)", height=6.0)
    a0.plot(t, plan["psi_dr"], color=PLAN_COLOUR)
    a0.plot(t, plan["q_psi1"], color="k", linestyle="--", linewidth=1.3)
    a0.set_ylabel("angle [rad]")
    a1.plot(t, plan["tau_drive"], color=PLAN_COLOUR)
    a1.set_ylabel(r"$\tau_\mathrm{dr}$ [N m]")
    a2.plot(t, plan["psi_dr"] - plan["q_psi1"], color=PLAN_COLOUR)
    a2.set_ylabel(r"$\psi_\mathrm{dr} - \psi_1$ [rad]")
    a0.set_title(r"displacement $\psi_\mathrm{dr}$ and planned $\psi_1$")
    a1.set_title(r"drive torque $\tau_\mathrm{dr}$")
    a2.set_title(r"drive twist $\psi_\mathrm{dr} - \psi_1$")
    time_limits(a2, t)
    bottom_legend(fig, [
        Line2D([], [], color=PLAN_COLOUR, label=r"drive displacement $\psi_\mathrm{dr}$"),
        Line2D([], [], color="k", linestyle="--", linewidth=1.3,
               label=r"planned joint angle $\psi_1$ (reference)")])
    return fig


def fig5_end_effector(plan, runs, ellipse):
    free = [r for r in runs if not r.friction]
    a, b = ellipse
    fig, (ax, az) = plt.subplots(1, 2, figsize=(7.0, 3.3),
                                 gridspec_kw={"width_ratios": [1.0, 1.25]})
    fig.suptitle("End-effector E, frictionless plant")
    th = np.linspace(0.0, 2.0 * np.pi, 721)
    ax.plot(a * np.cos(th), b * np.sin(th), color=GUIDE_COLOUR, linewidth=3.0, alpha=0.6,
            zorder=1)
    for r in free:
        st = run_style(r)
        ax.plot(r.data["E_x"], r.data["E_y"], **st)
        ax.plot(r.data["E_x"][0], r.data["E_y"][0], marker="o", markersize=5,
                color=st["color"], markeredgecolor="k", markeredgewidth=0.6, linestyle="none",
                zorder=6)
    ax.margins(0.06)  # the time axes have none; here the ellipse and start points need room
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(r"$x_E$ [m]")
    ax.set_ylabel(r"$y_E$ [m]")
    ax.set_title(r"(a) path in the $x$–$y$ plane")

    az.plot(plan["t"], plan["z_a"], color=GUIDE_COLOUR, linewidth=3.0, alpha=0.6, zorder=1)
    for r in free:
        az.plot(r.data["t"], r.data["E_z"], **run_style(r))
    az.set_xlabel(r"$t$ [s]")
    az.set_ylabel(r"$z_E$ [m]")
    az.set_title(r"(b) height $z_E(t)$")
    time_limits(az, plan["t"], *[r.data["t"] for r in free])

    handles = run_handles(free) + [
        Line2D([], [], color=GUIDE_COLOUR, linewidth=3.0, alpha=0.6,
               label=r"ellipse $(x/a)^2 + (y/b)^2 = 1$ / prescribed $z_a(t)$"),
        Line2D([], [], marker="o", markersize=5, color="0.85", markeredgecolor="k",
               markeredgewidth=0.6, linestyle="none", label="start point"),
    ]
    bottom_legend(fig, handles, ncol=3)
    return fig


def fig6_joints(runs):
    free = [r for r in runs if not r.friction]
    fig, axes = stacked(3, "Joint coordinates, frictionless plant")
    for ax, j in zip(axes, JOINTS):
        for r in free:
            ax.plot(r.data["t"], r.data[f"q_{j}"], **run_style(r))
        ax.set_ylabel(Q_LABEL[j])
    time_limits(axes[-1], *[r.data["t"] for r in free])
    bottom_legend(fig, run_handles(free))
    return fig


def errors_figure(runs, title, log):
    fig, axes = stacked(3, title)
    for ax, j in zip(axes, JOINTS):
        raw = []
        for r in runs:
            d = np.abs(r.data[f"e_{j}"])
            raw.append(d)
            ax.plot(r.data["t"], np.maximum(d, LOG_FLOOR) if log else d, **run_style(r))
        ax.set_ylabel(ERR_LABEL[j])
        if log:
            log_axis(ax)
        else:
            ax.set_ylim(bottom=0.0)
        note_negligible(ax, raw, ERR_SYMBOL[j], ERR_UNIT[j], log=log)
    time_limits(axes[-1], *[r.data["t"] for r in runs])
    bottom_legend(fig, run_handles(runs))
    return fig


def torques_figure(runs, title, t1=None):
    fig, axes = stacked(3, title)
    for ax, j in zip(axes, JOINTS):
        for r in runs:
            t, tau = r.data["t"], r.data[f"tau_{j}"]
            if t1 is not None:  # slice, so that the y range fits the window
                keep = t <= t1 + 1e-12
                t, tau = t[keep], tau[keep]
            ax.plot(t, tau, **run_style(r))
        ax.set_ylabel(TAU_LABEL[j])
    if t1 is None:
        time_limits(axes[-1], *[r.data["t"] for r in runs])
    else:
        axes[-1].set_xlim(min(float(r.data["t"][0]) for r in runs), t1)
    bottom_legend(fig, run_handles(runs))
    return fig


def fig9_friction(runs):
    fr = [r for r in runs if r.friction]
    fig, axes = plt.subplots(3, 2, sharex=True, figsize=(7.2, 6.3))
    fig.suptitle("Plant with LuGre friction: tracking errors and controller efforts")
    for i, j in enumerate(JOINTS):
        ae, at = axes[i, 0], axes[i, 1]
        for r in fr:
            st = run_style(r)
            ae.plot(r.data["t"], np.maximum(np.abs(r.data[f"e_{j}"]), FRICTION_LOG_FLOOR), **st)
            at.plot(r.data["t"], r.data[f"tau_{j}"], **st)
        log_axis(ae, FRICTION_LOG_FLOOR)
        ae.set_ylabel(ERR_LABEL[j])
        at.set_ylabel(TAU_LABEL[j])
        note_negligible(ae, [np.abs(r.data[f"e_{j}"]) for r in fr], ERR_SYMBOL[j], ERR_UNIT[j],
                        log=True, floor=FRICTION_LOG_FLOOR)
    fl = floor_text(FRICTION_LOG_FLOOR)
    axes[0, 0].set_title(f"absolute errors, log (values < {fl} drawn at {fl})")
    axes[0, 1].set_title("controller torques / force")
    for ax in axes[-1]:
        ax.set_xlabel(r"$t$ [s]")
    time_limits(axes[-1, 0], *[r.data["t"] for r in fr])
    bottom_legend(fig, run_handles(fr))
    return fig


def fig10_plan(plan):
    t = plan["t"]
    fig, axes = stacked(4, "Planned motion: constraint residuals and joint efforts", height=7.6)
    ar = axes[0]
    ar.plot(t, np.maximum(np.abs(plan["phi_ellipse"]), LOG_FLOOR), color=PLAN_COLOUR,
            linewidth=1.0)
    ar.plot(t, np.maximum(np.abs(plan["phi_height"]), LOG_FLOOR), color=PLAN_COLOUR2,
            linewidth=1.0)
    log_axis(ar)
    ar.set_ylabel(r"$|\Phi_i|$")
    fl = floor_text()
    ar.set_title(f"constraint residuals, log (values < {fl} drawn at {fl})")
    for k, (ax, j) in enumerate(zip(axes[1:], JOINTS), start=1):
        ax.plot(t, plan[f"required_{j}"], color="k", linewidth=1.3)
        ax.plot(t, plan[f"Qc_{j}"], color=QC_COLOUR, linestyle="--", linewidth=1.3)
        ax.set_ylabel(rf"$Q_{k}$ [{EFFORT_UNIT[j]}]")
        ax.set_title(f"efforts, {JOINT_NAME[j]}")
    time_limits(axes[-1], t)
    bottom_legend(fig, [
        Line2D([], [], color=PLAN_COLOUR, label=r"$|\Phi_1|$ (ellipse) [–]"),
        Line2D([], [], color=PLAN_COLOUR2, label=r"$|\Phi_2|$ (height) [m]"),
        Line2D([], [], color="k", linewidth=1.3, label="required effort (drive + constraint)"),
        Line2D([], [], color=QC_COLOUR, linestyle="--", linewidth=1.3,
               label=r"constraint force $Q_c$")], ncol=2)
    return fig


def build_figures(plan, runs, ellipse):
    free = [r for r in runs if not r.friction]
    perturbed = [r for r in free if not r.is_reference]
    fr = [r for r in runs if r.friction]
    figs = [
        ("fig4_drive", lambda: fig4_drive(plan)),
        ("fig5_end_effector", lambda: fig5_end_effector(plan, runs, ellipse)),
        ("fig6_joints", lambda: fig6_joints(runs)),
    ]
    if perturbed:
        floor = floor_text()
        figs += [
            ("fig7_errors", lambda: errors_figure(
                perturbed, "Absolute tracking errors, frictionless plant", log=False)),
            ("fig7_errors_log", lambda: errors_figure(
                perturbed, "Absolute tracking errors, frictionless plant "
                f"(log; values < {floor} drawn at {floor})", log=True)),
        ]
    else:
        warn("no frictionless run other than the 45 deg reference: fig7 skipped")
    figs += [
        ("fig8_torques", lambda: torques_figure(free, "Controller efforts, frictionless plant")),
        ("fig8_torques_first_second", lambda: torques_figure(
            free, f"Controller efforts, frictionless plant, first {ZOOM_T1:g} s", t1=ZOOM_T1)),
    ]
    if fr:
        figs.append(("fig9_friction", lambda: fig9_friction(runs)))
    else:
        warn("no run on the plant with friction: fig9 skipped")
    figs.append(("fig10_plan", lambda: fig10_plan(plan)))
    return figs


# ----------------------------------------------------------------------------- output

def render_all(figs, outdir):
    """Render every figure to temp files in outdir; return [(tmp, final)]."""
    pending = []
    try:
        for name, make in figs:
            fig = make()
            try:
                for ext in ("png", "pdf"):
                    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=f".{ext}.tmp",
                                               dir=outdir)
                    os.close(fd)
                    pending.append((tmp, os.path.join(outdir, f"{name}.{ext}")))
                    meta = {"CreationDate": None} if ext == "pdf" else {"Software": None}
                    fig.savefig(tmp, format=ext, dpi=DPI, metadata=meta)
            finally:
                plt.close(fig)
    except BaseException:
        for tmp, _ in pending:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        raise
    return pending


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 0 if len(argv) == 2 else 2
    results_dir = argv[1]
    try:
        plan, runs, ellipse = load_inputs(results_dir)
    except InputError as exc:
        print(f"refdyn: error: {one_line(exc)}", file=sys.stderr)
        return 2
    outdir = os.path.join(results_dir, "figures")
    plt.rcParams.update(RC)
    try:
        os.makedirs(outdir, exist_ok=True)
        pending = render_all(build_figures(plan, runs, ellipse), outdir)
        umask = os.umask(0)
        os.umask(umask)
        for tmp, _ in pending:
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; the CSVs get 0666 & ~umask
        for tmp, final in pending:
            os.replace(tmp, final)
    except OSError as exc:  # e.g. a read-only results folder: one line, nothing half-written
        print(f"refdyn: error: {one_line(getattr(exc, 'filename', None) or outdir)}: "
              f"cannot write ({one_line(exc.strerror or exc)})", file=sys.stderr)
        return 2
    for _, final in pending:
        print(final)
    for w in WARNINGS:
        print(w, file=sys.stderr)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except Exception as exc:  # noqa: BLE001 - a bug: one line, not a traceback
        print(f"refdyn: internal error: {PROG}: {type(exc).__name__}: {one_line(exc)} "
              "(please report)", file=sys.stderr)
        sys.exit(1)
