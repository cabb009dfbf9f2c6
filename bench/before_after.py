#!/usr/bin/env python3
"""Before/after timing of refdyn against an earlier commit, row by row (bench/README.md).

Builds COMMIT beside the checkout (`git archive` into ../refdyn-before-<sha>/src, Release, only
the benchmark targets), builds the same targets in the checkout's build directory, then runs the
two builds' benchmarks interleaved: for each round and each benchmark executable, before then
after, each run with REPETITIONS repetitions of the selected rows (Google Benchmark medians of
CPU time). Every run is pinned to one core (taskset), so both sides see the same core and the
same machine moments. Per row it prints the median over the rounds of each side and the ratio
after/before (< 1: the change made it faster); rows present in only one build are listed apart.

Usage:
  python3 bench/before_after.py COMMIT [--benches dynamics_bench,reference_dynamics_bench,implicit_bench]
      [--filter REGEX] [--rounds 3] [--repetitions 5] [--build-dir build] [--before-dir DIR]
      [--core 1] [--jobs 2] [--slower 1.05]
Examples:
  python3 bench/before_after.py main~5 --filter 'paper3|chain7/'
  python3 bench/before_after.py 14a8d28 --benches reference_dynamics_bench --filter 'CFD'

Exit status: 0, or 3 if any row got slower than --slower × before (a prompt to look, not a
verdict: check such a row again with more rounds before believing it).
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_ratios import medians  # noqa: E402  (Google Benchmark JSON -> median CPU ns per row)

DEFAULT_BENCHES = ["dynamics_bench", "reference_dynamics_bench", "implicit_bench"]


def sh(cmd, **kw):
    print("+ " + " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, **kw)


def build(src, build_dir, targets, jobs):
    """Configures (if needed) and builds `targets` of the tree `src` into `build_dir` (Release)."""
    if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
        sh(["cmake", "-S", src, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release", "-DREFDYN_BUILD_BENCHMARKS=ON"],
           stdout=subprocess.DEVNULL)
    sh(["cmake", "--build", build_dir, "-j", str(jobs), "--target"] + targets, stdout=subprocess.DEVNULL)


def run(binary, regex, repetitions, core):
    """Median CPU time (ns) per benchmark name from one run of `binary`."""
    fd, out = tempfile.mkstemp(suffix=".json")
    os.close(fd)
    try:
        cmd = [binary, "--benchmark_repetitions=%d" % repetitions, "--benchmark_report_aggregates_only=true",
               "--benchmark_out=" + out, "--benchmark_out_format=json"]
        if regex:
            cmd.append("--benchmark_filter=" + regex)
        if core is not None and shutil.which("taskset"):
            cmd = ["taskset", "-c", str(core)] + cmd
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(out) as f:
            data = json.load(f)
    finally:
        os.unlink(out)
    return medians(data)


def fmt_ns(x):
    if x < 1e4:
        return "%.0f ns" % x
    if x < 1e7:
        return "%.1f us" % (x / 1e3)
    return "%.2f ms" % (x / 1e6)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("commit", help="the earlier commit (any git revision)")
    ap.add_argument("--benches", default=",".join(DEFAULT_BENCHES), help="default: %(default)s")
    ap.add_argument("--filter", default="", help="Google Benchmark regex on row names (default: all rows)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repetitions", type=int, default=5)
    ap.add_argument("--build-dir", default="build", help="the checkout's build directory (default: %(default)s)")
    ap.add_argument("--before-dir", help="where COMMIT is unpacked and built (default: ../refdyn-before-<sha>)")
    ap.add_argument("--core", type=int, default=1, help="CPU the runs are pinned to (-1: not pinned)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--slower", type=float, default=1.05, help="after/before above this is flagged (exit 3)")
    ap.add_argument("--no-build", action="store_true", help="use the builds as they are")
    a = ap.parse_args()
    if a.rounds < 1 or a.repetitions < 1:
        ap.error("--rounds and --repetitions must be at least 1")

    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], check=True, capture_output=True,
                          text=True).stdout.strip()
    r = subprocess.run(["git", "-C", root, "rev-parse", "--verify", "--quiet", a.commit + "^{commit}"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("before_after.py: '%s' is not a commit of %s (try a hash, a tag, or main~N)" % (a.commit, root))
    sha = r.stdout.strip()
    before_root = os.path.abspath(a.before_dir or os.path.join(os.path.dirname(root), "refdyn-before-" + sha[:12]))
    before_src = os.path.join(before_root, "src")
    before_build = os.path.join(before_root, "build")
    after_build = os.path.abspath(os.path.join(root, a.build_dir))
    benches = [b for b in a.benches.split(",") if b]
    core = None if a.core < 0 else a.core

    if not a.no_build:
        if not os.path.isdir(before_src):
            os.makedirs(before_src + ".partial", exist_ok=True)
            archive = subprocess.Popen(["git", "-C", root, "archive", sha], stdout=subprocess.PIPE)
            subprocess.run(["tar", "-x", "-C", before_src + ".partial"], stdin=archive.stdout, check=True)
            if archive.wait() != 0:
                sys.exit("before_after.py: git archive %s failed" % sha)
            os.rename(before_src + ".partial", before_src)  # only a complete tree gets the name
        build(before_src, before_build, benches, a.jobs)
        build(root, after_build, benches, a.jobs)

    sides = {"before": os.path.join(before_build, "bench"), "after": os.path.join(after_build, "bench")}
    for side, d in sides.items():
        for b in benches:
            if not os.access(os.path.join(d, b), os.X_OK):
                sys.exit("before_after.py: no %s in %s (%s); build it or drop it from --benches" % (b, d, side))

    results = {b: {"before": [], "after": []} for b in benches}
    for rnd in range(a.rounds):
        for b in benches:
            for side in ("before", "after"):
                results[b][side].append(run(os.path.join(sides[side], b), a.filter, a.repetitions, core))
                print("round %d/%d: %s %s done" % (rnd + 1, a.rounds, b, side), file=sys.stderr)

    print("before: %s (%s)   after: %s (working tree)" % (a.commit, sha[:12], root))
    print("CPU time per call, median over %d rounds of the medians of %d repetitions; pinned to core %s"
          % (a.rounds, a.repetitions, "none" if core is None else core))
    flagged = 0
    for b in benches:
        names_b = [set(x) for x in results[b]["before"]]
        names_a = [set(x) for x in results[b]["after"]]
        common = set.intersection(*names_b, *names_a) if names_b and names_a else set()
        only = (set.union(*names_b, *names_a) if names_b else set()) - common
        print("\n### %s\n" % b)
        print("| row | before | after | after/before | per round after/before |")
        print("|---|---:|---:|---:|---|")
        ratios = []
        for name in sorted(common):
            bt = statistics.median(x[name] for x in results[b]["before"])
            at = statistics.median(x[name] for x in results[b]["after"])
            per = [y[name] / x[name] for x, y in zip(results[b]["before"], results[b]["after"])]
            ratio = at / bt
            ratios.append(ratio)
            mark = " **slower**" if ratio > a.slower else ""
            flagged += ratio > a.slower
            print("| %s | %s | %s | %.3f%s | %s |" % (name, fmt_ns(bt), fmt_ns(at), ratio, mark,
                                                    " ".join("%.3f" % p for p in per)))
        if ratios:
            gm = statistics.geometric_mean(ratios)
            print("\n%d rows; geometric mean of after/before %.3f; range %.3f–%.3f"
                  % (len(ratios), gm, min(ratios), max(ratios)))
        if only:
            print("\nrows in only one build (not compared): " + ", ".join(sorted(only)))
    if flagged:
        print("\n%d row(s) slower than %.2f × before" % (flagged, a.slower))
        sys.exit(3)


if __name__ == "__main__":
    main()
