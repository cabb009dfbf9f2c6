#!/usr/bin/env python3
"""Figures for any results folder written by `refdyn plan` or `refdyn track`.

Usage:  /usr/bin/python3 scripts/plot_results.py RESULTS_DIR

Writes RESULTS_DIR/figures/<name>.png (200 dpi) and .pdf:
  plan_joints       q, q' and q'' of the planned motion, one panel each, all joints
  plan_residuals    |Phi| and |dPhi/dt| of every constraint row (log scale)
  plan_efforts      required joint efforts (actuators + constraint forces) and Q_c
  plan_points       paths of the reported points in the x-y plane and their heights z(t)
  track_errors      |q - q_ref| of every experiment (log scale), one panel per joint
  track_efforts     controller torques/forces of every experiment, one panel per joint
Figures are rendered to temporary files and moved into place only after all of them
rendered, with mode 0666 minus the umask (like the CSV files). Any bad input (a missing,
empty, binary, non-UTF-8 or malformed file, a missing column) ends the program with one line
"refdyn: error: FILE: message" on stderr and exit status 2, and no figure is written.
"""

import glob
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

PROG = "plot_results.py"
FLOOR = 1e-16


class InputError(Exception):
    """A missing or malformed input; reported as one line, exit status 2."""


def one_line(msg):
    """The message with control characters (e.g. a newline in a folder name) escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(msg))


def fail(msg):
    raise InputError(msg)


def read_csv(path):
    """A numeric CSV with a header row: ({column: ndarray}, [columns]); InputError otherwise."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        fail(f"{path}: not found")
    except IsADirectoryError:
        fail(f"{path}: is a folder, expected a CSV file")
    except OSError as exc:
        fail(f"{path}: cannot read ({exc.strerror or exc})")
    if not raw.strip():
        fail(f"{path}: empty file, expected a header row")
    if b"\0" in raw:
        fail(f"{path}: binary data (NUL bytes), expected CSV text")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        fail(f"{path}: not UTF-8 text (byte {exc.start})")
    lines = text.splitlines()
    header = [h.strip() for h in lines[0].split(",")]
    if any(not h for h in header):
        fail(f"{path}:1: empty column name in the header")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        fail(f"{path}:1: duplicate column {one_line(dup[0])}")
    rows = []
    for n, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        values = line.split(",")
        if len(values) != len(header):
            fail(f"{path}:{n}: {len(values)} values, expected {len(header)} (one per header column)")
        try:
            rows.append([float(v) for v in values])
        except ValueError:
            bad = next(v for v in values if not _is_float(v))
            fail(f"{path}:{n}: not a number: {bad.strip()[:40]!r}")
    if not rows:
        fail(f"{path}: no data rows")
    data = np.array(rows, dtype=float)
    data[~np.isfinite(data)] = np.nan  # drawn as gaps
    return {h: data[:, i] for i, h in enumerate(header)}, header


def _is_float(v):
    try:
        float(v)
        return True
    except ValueError:
        return False


def columns(table, header, prefix):
    return [h[len(prefix):] for h in header if h.startswith(prefix)]


def need(table, name, path):
    if name not in table:
        fail(f"{path}: missing column {name}")
    return table[name]


def panels(n, title, height=2.0):
    fig, axes = plt.subplots(n, 1, figsize=(7.5, 1.2 + height * n), sharex=True, squeeze=False)
    fig.suptitle(title)
    return fig, axes[:, 0]


def main():
    if len(sys.argv) != 2:
        fail("usage: plot_results.py RESULTS_DIR")
    d = sys.argv[1]
    if not os.path.isdir(d):
        fail(f"{d}: not a folder")
    plan_path = os.path.join(d, "plan.csv")
    plan, ph = read_csv(plan_path)
    t = need(plan, "t", plan_path)
    joints = columns(plan, ph, "q_")
    if not joints:
        fail(f"{plan_path}: no q_<joint> columns")
    figs = {}

    fig, axes = panels(3, "Planned motion")
    for ax, pre, lab in zip(axes, ("q_", "qd_", "qdd_"), ("q", "q'", "q''")):
        for j in joints:
            ax.plot(t, need(plan, pre + j, plan_path), label=j)
        unit = {"q_": "rad or m", "qd_": "rad or m, per s", "qdd_": "rad or m, per s²"}[pre]
        ax.set_ylabel(f"{lab} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    figs["plan_joints"] = fig

    rows = columns(plan, ph, "phi_")
    if rows:
        fig, axes = panels(2, "Constraint residuals of the plan")
        for r in rows:
            axes[0].semilogy(t, np.maximum(np.abs(need(plan, "phi_" + r, plan_path)), FLOOR), label=r)
            axes[1].semilogy(t, np.maximum(np.abs(need(plan, "phid_" + r, plan_path)), FLOOR), label=r)
        axes[0].set_ylabel("|Phi|")
        axes[1].set_ylabel("|dPhi/dt|")
        for ax in axes:
            ax.grid(alpha=0.3, which="both")
        axes[0].legend(loc="best", fontsize=8)
        axes[-1].set_xlabel(f"t [s]   (values below {FLOOR:g} drawn at {FLOOR:g})")
        figs["plan_residuals"] = fig

    fig, axes = panels(len(joints), "Efforts the joints must deliver (plan)")
    for ax, j in zip(axes, joints):
        ax.plot(t, need(plan, "required_" + j, plan_path), label="required (actuators + constraint)")
        ax.plot(t, need(plan, "Qc_" + j, plan_path), "--", label="constraint force Q_c")
        ax.set_ylabel(j + " [N m or N]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    figs["plan_efforts"] = fig

    points = sorted({h[:-2] for h in ph if h.endswith("_x") and h[:-2] + "_y" in plan and h[:-2] + "_z" in plan})
    if points:
        fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.6))
        fig.suptitle("Reported points of the plan")
        for p in points:
            a.plot(plan[p + "_x"], plan[p + "_y"], label=p)
            b.plot(t, plan[p + "_z"], label=p)
        a.set_aspect("equal", adjustable="datalim")
        a.set_xlabel("x [m]")
        a.set_ylabel("y [m]")
        b.set_xlabel("t [s]")
        b.set_ylabel("z [m]")
        for ax in (a, b):
            ax.grid(alpha=0.3)
            ax.legend(loc="best", fontsize=8)
        figs["plan_points"] = fig

    tracks = sorted(glob.glob(os.path.join(d, "track_*.csv")))
    if tracks:
        data = []
        for path in tracks:
            tab, _ = read_csv(path)
            data.append((os.path.basename(path)[6:-4], tab, path))
        fig, axes = panels(len(joints), f"Tracking errors |q - q_ref| (values below {FLOOR:g} drawn at {FLOOR:g})")
        fig2, axes2 = panels(len(joints), "Controller efforts")
        for name, tab, path in data:
            tt = need(tab, "t", path)
            for ax, ax2, j in zip(axes, axes2, joints):
                ax.semilogy(tt, np.maximum(np.abs(need(tab, "e_" + j, path)), FLOOR), label=name)
                ax2.plot(tt, need(tab, "tau_" + j, path), label=name)
        for ax, ax2, j in zip(axes, axes2, joints):
            ax.set_ylabel(j)
            ax2.set_ylabel(j + " [N m or N]")
            ax.grid(alpha=0.3, which="both")
            ax2.grid(alpha=0.3)
        for axs, f in ((axes, fig), (axes2, fig2)):
            axs[-1].set_xlabel("t [s]")
            handles, labels = axs[0].get_legend_handles_labels()
            nrows = (len(labels) + 3) // 4
            f.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8)
            f.tight_layout(rect=(0, 0.04 + 0.05 * nrows, 1, 1))
        figs["track_errors"] = fig
        figs["track_efforts"] = fig2

    out = os.path.join(d, "figures")
    render_and_write(figs, out)


def render_and_write(figs, out):
    """Render every figure to temporary files in `out`, then move them all into place."""
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as exc:
        fail(f"{out}: cannot create the figures folder ({exc.strerror or exc})")
    umask = os.umask(0)
    os.umask(umask)
    staged = []
    try:
        for name, fig in figs.items():
            if not fig.get_tight_layout():
                fig.tight_layout()
            for ext in ("png", "pdf"):
                fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=f".{ext}.tmp", dir=out)
                os.close(fd)
                staged.append((tmp, os.path.join(out, f"{name}.{ext}")))
                fig.savefig(tmp, dpi=200, format=ext)
                os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; the CSVs get 0666 & ~umask
            plt.close(fig)
        for tmp, final in staged:
            os.replace(tmp, final)
    except BaseException as exc:
        for tmp, _ in staged:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        if isinstance(exc, OSError):
            fail(f"{getattr(exc, 'filename', None) or out}: cannot write ({exc.strerror or exc})")
        raise
    for _, final in staged:
        print(final)


if __name__ == "__main__":
    try:
        main()
    except InputError as exc:
        print(f"refdyn: error: {one_line(exc)}", file=sys.stderr)
        sys.exit(2)
    except Exception as exc:  # noqa: BLE001 - a bug: one line, not a traceback
        print(f"refdyn: internal error: {PROG}: {type(exc).__name__}: {one_line(exc)} (please report)",
              file=sys.stderr)
        sys.exit(1)
