#!/usr/bin/env bash
# Scaling of `refdyn track` over the runs of a sweep: runs/s with 1 and 2 threads, 1 and 2 MPI
# ranks, on the paper's manipulator with RUNS tracking runs (the study's two experiments, each
# swept over RUNS/2 start angles between 45° and 80°). Prints a Markdown table (bench/README.md).
#   usage: bench/sweep_scaling.sh [BUILD_DIR=build] [RUNS=200] [REPEATS=5]
# Each configuration runs REPEATS times, alternating with the others; the table has the median
# wall time of the whole command (load, plan, runs, files) and runs/s = RUNS / median. The files
# of every configuration are checked equal (summary.json up to wall times) once.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-200} repeats=${3:-5}
refdyn=$build/apps/refdyn
work=$(mktemp -d /tmp/refdyn_scaling.XXXXXX)
trap 'rm -rf "$work"' EXIT
half=$((runs / 2))
values=$(python3 -c "n=$half; print(', '.join(repr(45 + 35*i/max(n-1,1)) for i in range(n)))")
sed "s/sweep: {alpha0: \[45, 60, 70, 80\]}/sweep: {alpha0: [$values]}/" examples/paper/paper.yaml > "$work/sweep.yaml"
grep -q "alpha0: \[45.0" "$work/sweep.yaml" || { echo "sweep_scaling: could not make the sweep scenario" >&2; exit 1; }
MPI=(mpirun --oversubscribe)
[ "$(id -u)" -eq 0 ] && MPI+=(--allow-run-as-root)
declare -A cmd=(
  [threads1]="$refdyn track $work/sweep.yaml -q --run-csv none -j 1 -o"
  [threads2]="$refdyn track $work/sweep.yaml -q --run-csv none -j 2 -o"
  [ranks1]="${MPI[*]} -np 1 $refdyn track $work/sweep.yaml -q --run-csv none --mpi -j 1 -o"
  [ranks2]="${MPI[*]} -np 2 $refdyn track $work/sweep.yaml -q --run-csv none --mpi -j 1 -o"
  [threads1_csv]="$refdyn track $work/sweep.yaml -q --run-csv all -j 1 -o"
  [threads2_csv]="$refdyn track $work/sweep.yaml -q --run-csv all -j 2 -o"
)
order=(threads1 threads2 ranks1 ranks2 threads1_csv threads2_csv)
command -v mpirun > /dev/null || order=(threads1 threads2 threads1_csv threads2_csv)
declare -A times
for ((r = 0; r < repeats; r++)); do
  for c in "${order[@]}"; do
    rm -rf "$work/out_$c"
    t0=$(date +%s.%N)
    ${cmd[$c]} "$work/out_$c"
    t1=$(date +%s.%N)
    times[$c]="${times[$c]:-} $(python3 -c "print($t1 - $t0)")"
  done
done
for c in "${order[@]}"; do  # same files as one thread
  for f in "$work/out_threads1"/*; do
    b=$(basename "$f")
    [ "$b" = summary.json ] && continue
    cmp -s "$f" "$work/out_$c/$b" || { echo "sweep_scaling: $c: $b differs from one thread" >&2; exit 1; }
  done
done
plan_t0=$(date +%s.%N); "$refdyn" plan "$work/sweep.yaml" -q -o "$work/plan_only"; plan_t1=$(date +%s.%N)
rss() { /usr/bin/time -f %M "$@" 2>&1 >/dev/null | tail -1; }
sed "s/sweep: {alpha0: \[[^]]*\]}/sweep: {alpha0: [45, 80]}/" "$work/sweep.yaml" > "$work/small.yaml"
rss_small=$(rss "$refdyn" track "$work/small.yaml" -q --run-csv none -j 2 -o "$work/rss_small")
rss_big=$(rss "$refdyn" track "$work/sweep.yaml" -q --run-csv none -j 2 -o "$work/rss_big")
echo "runs: $runs (paper manipulator, 5 s, RK4 1 ms), repeats: $repeats, $(nproc) cores, $(date -u +%F)"
echo
echo "| configuration | median wall time [s] | runs/s | speed-up vs 1 |"
echo "|---|---|---|---|"
python3 - "$runs" "$(declare -p times)" "${order[@]}" <<'PY'
import re, statistics, sys
runs = int(sys.argv[1]); decl = sys.argv[2]; order = sys.argv[3:]
t = {k: [float(x) for x in v.split()] for k, v in re.findall(r'\[(\w+)\]=" ?([^"]*)"', decl)}
med = {k: statistics.median(v) for k, v in t.items()}
base = {'threads1': 'threads1', 'threads2': 'threads1', 'ranks1': 'ranks1', 'ranks2': 'ranks1',
        'threads1_csv': 'threads1_csv', 'threads2_csv': 'threads1_csv'}
label = {'threads1': '1 thread', 'threads2': '2 threads', 'ranks1': 'mpirun -np 1 (--mpi)', 'ranks2': 'mpirun -np 2 (--mpi, 1 thread each)',
         'threads1_csv': '1 thread, per-run CSVs', 'threads2_csv': '2 threads, per-run CSVs'}
for k in order:
    print(f"| {label[k]} | {med[k]:.3f} (min {min(t[k]):.3f}) | {runs/med[k]:.1f} | {med[base[k]]/med[k]:.2f}x |")
PY
echo
echo "serial part (load + plan + plan.csv, \`refdyn plan\`): $(python3 -c "print(round($plan_t1 - $plan_t0, 3))") s"
echo "peak RSS, 2 threads, no per-run CSVs: $rss_small kB with 2 runs, $rss_big kB with $runs runs"
