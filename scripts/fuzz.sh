#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/: expression parser, scenario parser,
# problem builder, code generator on random chains) with clang and
# -fsanitize=fuzzer,address,undefined into build-asan/ (the sanitizer suite's build, configured
# the same way: scripts/test-sanitizers.sh), and runs each for SECONDS (default 60), JOBS
# targets at a time.
#   bash scripts/fuzz.sh [SECONDS]
# Seed corpora are made at run time from tests/data/** and examples/**/*.yaml (nothing is
# committed). A finding (crash, any exception other than refdyn::Error, leak, UB, timeout,
# out-of-memory) stops that target; its input is kept as build-asan/findings/<target>/crash-*,
# leak-*, timeout-* or oom-*, and the script exits 1 after running all targets.
# Environment: FUZZ_BUILD_DIR (build-asan), FUZZ_OUT (build-asan/findings), FUZZ_TARGETS (both),
# FUZZ_CORPUS_DIR (keep the grown corpora there instead of a temporary folder), JOBS.
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-60}
[[ "$SECS" =~ ^[0-9]+$ ]] || { echo "usage: scripts/fuzz.sh [SECONDS]" >&2; exit 1; }
BUILD_DIR=${FUZZ_BUILD_DIR:-${ASAN_BUILD_DIR:-build-asan}}
OUT=${FUZZ_OUT:-$BUILD_DIR/findings}
TARGETS=${FUZZ_TARGETS:-expression_fuzz scenario_fuzz problem_fuzz generate_fuzz}
JOBS=${JOBS:-$(nproc)}
CXX_FUZZ=${CXX_FUZZ:-${SANITIZER_CXX:-clang++-14}}
CC_FUZZ=${CC_FUZZ:-${SANITIZER_CC:-clang-14}}

bash scripts/install-deps.sh
mkdir -p "$BUILD_DIR"
# The configuration of scripts/test-sanitizers.sh (-O1 -g1, clang, ASan + UBSan): after the
# sanitizer suite the library is up to date and only the four fuzz executables are compiled
# (the stage's measured time is in docs/testing.md, "CI time").
bash scripts/configure.sh "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1" -DCMAKE_CXX_COMPILER="$CXX_FUZZ" -DCMAKE_C_COMPILER="$CC_FUZZ" \
  -DREFDYN_SANITIZE=address,undefined -DREFDYN_FUZZ=ON > "$BUILD_DIR/configure.log" 2>&1 ||
  { cat "$BUILD_DIR/configure.log"; exit 1; }
# shellcheck disable=SC2086
cmake --build "$BUILD_DIR" -j "$JOBS" --target $TARGETS

if [[ -n "${FUZZ_CORPUS_DIR:-}" ]]; then
  WORK=$FUZZ_CORPUS_DIR
  mkdir -p "$WORK"
else
  WORK=$(mktemp -d /tmp/refdyn_fuzz.XXXXXX)
  trap 'rm -rf "$WORK"' EXIT
fi

# Seeds. Scenario parser and problem builder: every file below tests/data and every example
# scenario.
mkdir -p "$WORK/scenario_fuzz" "$WORK/expression_fuzz" "$WORK/problem_fuzz" "$WORK/generate_fuzz"
n=0
while IFS= read -r -d '' f; do
  cp "$f" "$WORK/scenario_fuzz/seed_$n"
  cp "$f" "$WORK/problem_fuzz/seed_$((n++))"
done < <(find tests/data examples -type f \( -path 'tests/data/*' -o -name '*.yaml' \) -print0 | sort -z)
# Expression parser: the right-hand sides of the scenario files (expressions, parameters,
# time functions) and a few texts over its variables t, x(E), q(j1) and parameter a.
n=0
while IFS= read -r line; do
  printf '%s' "$line" > "$WORK/expression_fuzz/seed_$((n++))"
done < <(find tests/data examples -name '*.yaml' -print0 | sort -z | xargs -0 cat |
         sed -n 's/^[^#:]*:[[:space:]]*\([^#{[][^#]*\).*$/\1/p' | sed 's/[[:space:]]*$//' | grep -v '^$' | sort -u)
for e in 't' 'a*t^2 + sin(x(E))*q(j1)' 'sqrt(1 + x(E)^2)/(a - cos(q(j1)))' 'atan2(x(E), t) - exp(-a*t)' \
         'abs(q(j1))^3 + log(2 + t^2)' 'tanh(x(E)/0.01)*pow(t, 3)' '(x(E) - 0.5)^2 + (q(j1) + a)^2 - 1'; do
  printf '%s' "$e" > "$WORK/expression_fuzz/seed_$((n++))"
done

# Generator: bytes that choose a small chain (fuzz/generate_fuzz.cpp); eight fixed patterns.
for i in 1 2 3 4 5 6 7 8; do
  LC_ALL=C awk -v i="$i" 'BEGIN { for (k = 0; k < 96; ++k) printf "%c", (i * 37 + k * (11 + i)) % 256 }' \
    > "$WORK/generate_fuzz/seed_$i"
done

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:symbolize=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
SYMB=$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)
[[ -n "$SYMB" ]] && export ASAN_SYMBOLIZER_PATH=$SYMB

run_target() {  # TARGET: runs one target for SECS, prints its result; exit 1 on a finding
  local t=$1 log="$OUT/$1.log" rc execs
  mkdir -p "$OUT/$t"
  echo "fuzz: $t for ${SECS}s (seeds: $(ls "$WORK/$t" | wc -l), findings go to $OUT/$t/, log $log)"
  set +e
  "$BUILD_DIR/fuzz/$t" -max_total_time="$SECS" -rss_limit_mb=2048 -timeout=20 -max_len=8192 \
    -print_final_stats=1 -artifact_prefix="$OUT/$t/" "$WORK/$t" > "$log" 2>&1
  rc=$?
  set -e
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [[ $rc -eq 0 ]]; then
    echo "fuzz: $t: OK, ${execs:-?} executions in ${SECS}s, no finding"
    return 0
  fi
  echo "fuzz: $t: FINDING (exit $rc) after ${execs:-?} executions; input kept:" \
       "$(ls -t "$OUT/$t" | head -1 | sed "s|^|$OUT/$t/|")"
  grep -m1 -E 'ERROR: |runtime error:|terminate called|uncaught exception|==ERROR' "$log" || true
  echo "fuzz: full report in $log"
  return 1
}

# JOBS targets at a time (each libFuzzer process uses one core).
status=0
declare -a pids=()
for t in $TARGETS; do
  run_target "$t" &
  pids+=($!)
  if (( ${#pids[@]} >= JOBS )); then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do
  wait "$p" || status=1
done
exit $status
