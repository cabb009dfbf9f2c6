#!/usr/bin/env python3
"""Overhead of the Python module (issue 12).

1. One plan of the paper example (examples/paper/paper.yaml, RK4 0-5 s, h = 1 ms, 5001
   samples) from Python against C++, the same work on both sides: run_problem on a loaded
   Problem, the plan's trajectory table, and freeing both.
     Python: refdyn.run(problem) (GIL released during run_problem), its .plan Trajectory
             (NumPy array + dataclass), then del.
     C++:    build/python/refdyn_plan_timing (python/plan_timing.cpp): io::run_problem +
             io::trajectory_table, then their destructors.
   Alternating batches (C++ batch, Python batch) so that both see the same machine load;
   medians over all repetitions and their ratio are printed.
2. Per-call time of Model.mass_matrix(q) from Python (paper model, nq = 3), next to the cost of
   an empty Python call; the C++ time of the same function is paper3/M/recursive of
   bench/dynamics_bench (bench/README.md): the difference is the binding's overhead.

Build: cmake --build build -j2 --target refdyn_python refdyn_plan_timing
Usage: PYTHONPATH=build/python /usr/bin/python3 bench/python_overhead.py [--batches 5 --reps 5]
"""
import argparse
import pathlib
import statistics
import subprocess
import time
import timeit

import numpy as np
import refdyn

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAPER = ROOT / "examples" / "paper" / "paper.yaml"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batches", type=int, default=5)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--timing", default=str(ROOT / "build" / "python" / "refdyn_plan_timing"))
    ap.add_argument("--calls", type=int, default=200000)
    args = ap.parse_args()

    problem = refdyn.load(PAPER)
    refdyn.run(problem)  # warm-up
    py, cpp, py_cpu, cpp_cpu = [], [], [], []
    for _ in range(args.batches):
        out = subprocess.run([args.timing, str(PAPER), str(args.reps + 1)], check=True,
                             capture_output=True, text=True).stdout.split("\n")
        cpp += [float(line.split()[0]) for line in out[1:] if line]  # first: warm-up
        cpp_cpu += [float(line.split()[1]) for line in out[1:] if line]
        for _ in range(args.reps):
            t, c = time.perf_counter(), time.thread_time()  # run_problem runs in this thread
            r = refdyn.run(problem)
            plan = r.plan
            cells = plan.data.size
            del r, plan
            py_cpu.append(time.thread_time() - c)
            py.append(time.perf_counter() - t)
            assert cells == 5001 * 31
    print(f"paper plan (run_problem + plan table + free), {len(cpp)} C++ / {len(py)} Python repetitions:")
    for what, c_, p_ in (("wall", cpp, py), ("thread CPU", cpp_cpu, py_cpu)):
        mc, mp = statistics.median(c_), statistics.median(p_)
        print(f"  {what:>10}: C++ median {mc * 1e3:6.2f} ms (min {min(c_) * 1e3:6.2f}),"
              f" Python median {mp * 1e3:6.2f} ms (min {min(p_) * 1e3:6.2f}), ratio of medians {mp / mc:.3f}")

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
