#!/usr/bin/env bash
# refdyn track --mpi under mpirun (2 and 3 ranks) writes the files one process writes: every
# file byte for byte, summary.json up to its wall times. A bad scenario under mpirun: exit 2 on
# every rank, one error line (from rank 0), nothing written.
#   usage: mpi_test.sh REFDYN MPIRUN SOURCE_DIR WORK_DIR
set -euo pipefail
refdyn=$1 mpirun=$2 src=$3 work=$4
scenario=$src/tests/data/good/sweep_arm.yaml
rm -rf "$work"
mkdir -p "$work"
MPI=("$mpirun" --oversubscribe)
if [ "$(id -u)" -eq 0 ]; then MPI+=(--allow-run-as-root); fi
fail=0
no_wall() { sed -E 's/"wall_time_s": [^,}]*[,]? ?//g' "$1"; }
same_files() {  # DIR_A DIR_B
  local n=0
  for f in "$1"/*; do
    [ -d "$f" ] && continue  # folders (variants) are compared one by one
    n=$((n + 1))
    local b
    b=$(basename "$f")
    if [ "$b" = summary.json ]; then
      if ! diff <(no_wall "$f") <(no_wall "$2/$b") > /dev/null; then echo "FAIL: $b differs ($1 vs $2)"; fail=1; fi
    elif ! cmp -s "$f" "$2/$b"; then
      echo "FAIL: $b differs ($1 vs $2)"; fail=1
    fi
  done
  local m
  m=$(find "$2" -maxdepth 1 -type f | wc -l)
  if [ "$m" -ne "$n" ]; then echo "FAIL: $2 has $m files, $1 has $n"; fail=1; fi
  echo "compared $n files: $1 vs $2"
}
"$refdyn" track "$scenario" -o "$work/serial" -q -j 1
for np in 2 3; do
  "${MPI[@]}" -np $np "$refdyn" track "$scenario" -o "$work/mpi$np" -q --mpi
  same_files "$work/serial" "$work/mpi$np"
done
# Two ranks with two threads each.
"${MPI[@]}" -np 2 "$refdyn" track "$scenario" -o "$work/mpi2j2" -q --mpi --jobs 2
same_files "$work/serial" "$work/mpi2j2"
# A family of variants (one plan each) over 2 ranks: variants.csv and every variant's folder
# as one process writes them.
family=$src/examples/planar_2r_circle/family.yaml
"$refdyn" plan "$family" -o "$work/family_serial" -q -j 1
"${MPI[@]}" -np 2 "$refdyn" plan "$family" -o "$work/family_mpi" -q --mpi
same_files "$work/family_serial" "$work/family_mpi"
for d in "$work/family_serial"/*/; do
  same_files "${d%/}" "$work/family_mpi/$(basename "$d")"
done
# --report: rank 0 writes the report from the folder; it equals one process's report (which
# is made from memory) up to the wall times embedded with summary.json.
if "$refdyn" track "$scenario" -o "$work/serial_report" -q -j 1 --report 2> /dev/null; then
  "${MPI[@]}" -np 2 "$refdyn" track "$scenario" -o "$work/mpi_report" -q --mpi --report
  if ! diff <(no_wall "$work/serial_report/report.html") <(no_wall "$work/mpi_report/report.html") > /dev/null; then
    echo "FAIL: report.html under mpirun differs from one process's"; fail=1
  else
    echo "report.html: the same under mpirun -np 2"
  fi
else
  echo "(no report: refdyn built without the report's JavaScript libraries)"
fi
# A scenario that does not load: exit 2, one line, nothing written.
set +e
err=$("${MPI[@]}" -np 2 "$refdyn" track "$work/missing.yaml" -o "$work/bad" -q --mpi 2>&1 >/dev/null)
rc=$?
set -e
lines=$(printf '%s\n' "$err" | grep -c "refdyn: error:" || true)
if [ $rc -eq 0 ]; then echo "FAIL: a missing scenario under mpirun exited 0"; fail=1; fi
if [ "$lines" -ne 1 ]; then echo "FAIL: expected one 'refdyn: error:' line, got $lines: $err"; fail=1; fi
if [ -e "$work/bad" ]; then echo "FAIL: $work/bad was created"; fail=1; fi
[ $fail -eq 0 ] && echo "mpi_test: OK"
exit $fail
