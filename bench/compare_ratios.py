#!/usr/bin/env python3
"""Interleaved before/after comparison of dynamics_bench's refdyn/KDL ratios (bench/README.md).

Runs two dynamics_bench binaries alternately (before, after, before, after, ... ROUNDS times
each), each run with REPETITIONS interleaved repetitions of the selected rows, and prints per row
the medians of CPU time over all repetitions of each binary and the ratio KDL/refdyn (> 1: refdyn
is faster), which is computed per run (both sides of a ratio come from the same process) and
then taken as the median over the rounds. "change" is after ratio / before ratio − 1: the
speed of refdyn relative to KDL moved by that much (negative: refdyn lost ground).

Optionally (--cli-before/--cli-after SCENARIO) it also times one whole `refdyn track` command per
round and binary (wall time, alternating, `-j 1 --run-csv none`), e.g. a 10 s simulation.

Usage:
  python3 bench/compare_ratios.py BEFORE_BENCH AFTER_BENCH [--rounds 3] [--repetitions 5]
      [--rows REGEX] [--cli-before REFDYN --cli-after REFDYN --scenario FILE]
Example (the issue-20 check):
  python3 bench/compare_ratios.py /work/base/build/bench/dynamics_bench build/bench/dynamics_bench
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

# (model, quantity, refdyn route, KDL peer routes in order of preference: older binaries name
# the KKT peer CFD/kdl, newer ones CFD/kdl_kkt).
MODELS = ["paper3", "chain7", "chain60"]
ROWS = [
    ("M", "recursive", ["kdl"]),
    ("c+g", "recursive", ["kdl"]),
    ("ID", "recursive", ["kdl"]),
    ("FD", "auto", ["kdl"]),
    ("CFD", "auto", ["kdl_kkt", "kdl"]),
    ("CFDtip", "auto", ["kdl_vereshchagin"]),
]


def run_bench(binary, regex, repetitions):
    """Median CPU time (ns) per benchmark name from one run of `binary`."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out = f.name
    try:
        cmd = [binary, "--benchmark_filter=" + regex, "--benchmark_repetitions=%d" % repetitions,
               "--benchmark_report_aggregates_only=true", "--benchmark_out=" + out,
               "--benchmark_out_format=json"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(out) as f:
            data = json.load(f)
    finally:
        os.unlink(out)
    return medians(data)


def medians(data):
    """Median CPU time (ns) per benchmark name from Google Benchmark's JSON (aggregates)."""
    med = {}
    for b in data.get("benchmarks", []):
        if b.get("run_type") == "aggregate" and b.get("aggregate_name") == "median":
            scale = {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}[b.get("time_unit", "ns")]
            med[b["run_name"]] = b["cpu_time"] * scale
    return med


def time_track(refdyn, scenario):
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        subprocess.run([refdyn, "track", scenario, "-o", d, "-j", "1", "--run-csv", "none"], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - t


def fmt_ns(x):
    return "%.0f ns" % x if x < 1e4 else "%.1f us" % (x / 1e3)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repetitions", type=int, default=5)
    ap.add_argument("--models", default=",".join(MODELS), help="comma-separated (default: %(default)s)")
    ap.add_argument("--quantities", default=",".join(r[0] for r in ROWS), help="default: %(default)s")
    ap.add_argument("--cli-before", help="refdyn binary (before) for the whole-command timing")
    ap.add_argument("--cli-after", help="refdyn binary (after)")
    ap.add_argument("--scenario", help="scenario file for `refdyn track` (with --cli-before/--cli-after)")
    a = ap.parse_args()
    models = a.models.split(",")
    rows = [r for r in ROWS if r[0] in a.quantities.split(",")]
    names = set()
    for q, route, peers in rows:
        names.add(q + "/" + route)
        names.update(q + "/" + p for p in peers)
    regex = "^(%s)/(%s)$" % ("|".join(models), "|".join(sorted(n.replace("+", "\\+") for n in names)))
    runs = {"before": [], "after": []}
    cli = {"before": [], "after": []}
    for r in range(a.rounds):
        for side in ("before", "after"):
            runs[side].append(run_bench(getattr(a, side), regex, a.repetitions))
            print("round %d/%d: %s done" % (r + 1, a.rounds, side), file=sys.stderr)
            if a.cli_before and a.cli_after and a.scenario:
                cli[side].append(time_track(getattr(a, "cli_" + side), a.scenario))

    print("| model | quantity | KDL peer | before refdyn | before KDL | before KDL/refdyn | after refdyn | "
          "after KDL | after KDL/refdyn | change | per-round ratios before / after |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
    worst = 0.0
    for m in models:
        for q, route, peers in rows:
            ours = m + "/" + q + "/" + route
            cols, ratios = [], {}
            peer_used = None
            for side in ("before", "after"):
                rs, ts, ks = [], [], []
                for res in runs[side]:
                    peer = next((m + "/" + q + "/" + p for p in peers if m + "/" + q + "/" + p in res), None)
                    if ours in res and peer:
                        peer_used = peer.split("/")[-1]
                        ts.append(res[ours])
                        ks.append(res[peer])
                        rs.append(res[peer] / res[ours])
                if not rs:
                    break
                ratios[side] = rs
                cols += [fmt_ns(statistics.median(ts)), fmt_ns(statistics.median(ks)), "%.2f" % statistics.median(rs)]
            if len(ratios) < 2:
                continue
            change = statistics.median(ratios["after"]) / statistics.median(ratios["before"]) - 1
            worst = min(worst, change)
            per = " ".join("%.2f" % x for x in ratios["before"]) + " / " + " ".join("%.2f" % x for x in ratios["after"])
            print("| %s | %s | %s | %s | %+.1f %% | %s |" % (m, q, peer_used, " | ".join(cols), 100 * change, per))
    if cli["before"]:
        b, f = statistics.median(cli["before"]), statistics.median(cli["after"])
        print("\n`refdyn track %s -j 1 --run-csv none`, wall time, median of %d alternating runs: before %.3f s, "
              "after %.3f s, after/before %.3f" % (a.scenario, a.rounds, b, f, f / b))
    print("\nlargest loss of a ratio: %.1f %%" % (100 * worst))


if __name__ == "__main__":
    main()
