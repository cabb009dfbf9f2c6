#!/usr/bin/env python3
"""Overhead of the Python module (issue 12).

1. One plan of the paper example (examples/paper/paper.yaml, RK4 0-5 s, h = 1 ms) from Python
   (refdyn.plan on a loaded Problem: run_problem + the trajectory table as a NumPy array +
   the dataclass) against C++ (`refdyn plan paper.yaml -q`: run_problem's wall time, the
   "wall_time_s" of summary.json, i.e. without process start-up and file writing). The two
   alternate, REPS times each; medians and their ratio are printed.
2. Per-call time of Model.mass_matrix(q) from Python (paper model, nq = 3), next to the cost
   of an empty Python call; the C++ time of the same function is paper3/M/recursive of
   bench/dynamics_bench (bench/README.md), the difference is the binding's overhead.

Usage: PYTHONPATH=build/python /usr/bin/python3 bench/python_overhead.py [--reps 7] [--cli build/apps/refdyn]
"""
import argparse
import json
import pathlib
import statistics
import subprocess
import tempfile
import time
import timeit

import numpy as np
import refdyn

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAPER = ROOT / "examples" / "paper" / "paper.yaml"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--cli", default=str(ROOT / "build" / "apps" / "refdyn"))
    ap.add_argument("--calls", type=int, default=200000)
    args = ap.parse_args()

    problem = refdyn.load(PAPER)
    py_total, py_core, cpp = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.reps):
            subprocess.run([args.cli, "plan", str(PAPER), "-q", "-o", tmp], check=True)
            cpp.append(json.loads((pathlib.Path(tmp) / "summary.json").read_text())["wall_time_s"])
            t = time.perf_counter()
            r = refdyn.run(problem)
            plan = r.plan
            py_total.append(time.perf_counter() - t)
            py_core.append(r.wall_time)
            assert plan.ok and plan.data.shape[0] == 5001
    mc, mp, mpc = statistics.median(cpp), statistics.median(py_total), statistics.median(py_core)
    print(f"paper plan, {args.reps} alternating runs each (median):")
    print(f"  C++  (refdyn plan, run_problem wall time)       {mc * 1e3:8.1f} ms")
    print(f"  Python refdyn.run(problem).plan, total           {mp * 1e3:8.1f} ms  ratio {mp / mc:.3f}")
    print(f"  Python, of which run_problem (GIL released)     {mpc * 1e3:8.1f} ms  ratio {mpc / mc:.3f}")

    model = problem.model
    q = np.array([0.3, 1.25 * np.pi, 0.5])
    model.mass_matrix(q)
    n = args.calls
    per = []
    for _ in range(5):
        per.append(timeit.timeit(lambda: model.mass_matrix(q), number=n) / n)
    empty = min(timeit.repeat(lambda: None, number=n, repeat=5)) / n
    print(f"Model.mass_matrix(q) from Python, paper model: median {statistics.median(per) * 1e9:.0f} ns/call "
          f"(min {min(per) * 1e9:.0f}; an empty lambda call costs {empty * 1e9:.0f} ns)")


if __name__ == "__main__":
    main()
