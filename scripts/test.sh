#!/usr/bin/env bash
# The whole test suite (= CI, .ci/run):
#   1. builds everything (library, CLI, tests, benchmarks, examples) into build/ and runs CTest;
#   2. the sanitizer suite: ASan + UBSan build in build-asan/, CTest (scripts/test-sanitizers.sh);
#   3. each libFuzzer target for 60 s, two at a time (scripts/fuzz.sh; its targets are built in
#      build-asan/, which the sanitizer stage compiled with the fuzzer's instrumentation).
# Every stage runs even if an earlier one failed; the script prints one line per stage and
# exits non-zero if any failed. For a quick local run:
#   REFDYN_SANITIZERS=0 REFDYN_FUZZ_SECONDS=0 bash scripts/test.sh
# See docs/testing.md.
set -uo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh || exit 1
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}
FUZZ_SECONDS=${REFDYN_FUZZ_SECONDS:-60}
declare -a summary=()
failed=0
stage() {  # NAME COMMAND...: runs the command, records PASS/FAIL and its duration
  local name=$1 start=$SECONDS rc
  shift
  echo "==== test.sh: $name"
  "$@"
  rc=$?
  if [[ $rc -eq 0 ]]; then
    summary+=("PASS  $name ($((SECONDS - start)) s)")
  else
    summary+=("FAIL  $name (exit $rc, $((SECONDS - start)) s)")
    failed=1
  fi
  return $rc
}
CTEST_LOG=$(mktemp /tmp/refdyn_ctest.XXXXXX)
trap 'rm -f "$CTEST_LOG"' EXIT
normal_suite() {
  bash scripts/configure.sh "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release &&
    cmake --build "$BUILD_DIR" -j "$JOBS" &&
    (cd "$BUILD_DIR" && ctest --output-on-failure -j "$JOBS" | tee "$CTEST_LOG"; exit "${PIPESTATUS[0]}")
}

stage "build + tests ($BUILD_DIR)" normal_suite
if [[ "${REFDYN_SANITIZERS:-1}" != 0 ]]; then
  stage "sanitizers: ASan + UBSan build + tests (build-asan)" env JOBS="$JOBS" bash scripts/test-sanitizers.sh
fi
if [[ "$FUZZ_SECONDS" != 0 ]]; then
  # Exploratory fuzzing reports what it finds (input kept in build-asan/findings/) but does not
  # fail the suite unless REFDYN_FUZZ_FATAL=1: a new finding is a new issue to fix, not a
  # regression of what was merged (the reproducers of past findings are regression tests: they
  # are in the seed corpus and in the unit tests).
  if [[ "${REFDYN_FUZZ_FATAL:-0}" == 1 ]]; then
    stage "fuzzing: ${FUZZ_SECONDS} s per target (build-asan)" env JOBS="$JOBS" bash scripts/fuzz.sh "$FUZZ_SECONDS"
  else
    fuzz_start=$SECONDS
    echo "==== test.sh: fuzzing: ${FUZZ_SECONDS} s per target (build-asan; findings reported, not fatal)"
    if env JOBS="$JOBS" bash scripts/fuzz.sh "$FUZZ_SECONDS"; then
      summary+=("PASS  fuzzing: ${FUZZ_SECONDS} s per target, no finding ($((SECONDS - fuzz_start)) s)")
    else
      summary+=("NOTE  fuzzing: a finding or a build failure, see above and build-asan/findings/ ($((SECONDS - fuzz_start)) s)")
    fi
  fi
fi
echo "==== test.sh: summary"
printf '  %s\n' "${summary[@]}"
# The main suite's counts as the closing line ("N passed, N failed"), from ctest's own summary.
counts=$(grep -E '^[0-9]+% tests passed, [0-9]+ tests? failed out of [0-9]+' "$CTEST_LOG" | tail -n 1)
if [[ -n "$counts" ]]; then
  total=${counts##* out of }
  bad=$(sed -E 's/.* ([0-9]+) tests? failed.*/\1/' <<<"$counts")
  echo "ctest: $((total - bad)) passed, $bad failed"
fi
exit $failed
