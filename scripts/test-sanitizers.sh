#!/usr/bin/env bash
# Builds refdyn with AddressSanitizer + UndefinedBehaviorSanitizer (clang; -O1 -g1, assertions and
# Eigen's bounds checks on, no -march=native, no benchmarks) into build-asan/ and runs the
# whole CTest suite there. Any sanitizer report fails the test that triggered it.
# The same build holds the libFuzzer targets (REFDYN_FUZZ=ON: everything also carries the
# fuzzer's coverage instrumentation), so scripts/fuzz.sh reuses it instead of compiling the
# library a third time (docs/testing.md, "CI time").
#   bash scripts/test-sanitizers.sh            # REFDYN_SANITIZE=address,undefined
#   REFDYN_SANITIZE=undefined bash scripts/test-sanitizers.sh    # gcc or clang, no fuzz targets
#   SANITIZER_CXX=g++ SANITIZER_CC=gcc bash scripts/test-sanitizers.sh   # gcc, no fuzz targets
# Environment: ASAN_BUILD_DIR (build-asan), REFDYN_SANITIZE, SANITIZER_CXX (clang++-14),
# SANITIZER_CC (clang-14), JOBS (nproc).
# Tests that interpose malloc (allocation counters) are not built with ASan (tests/CMakeLists.txt).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD_DIR=${ASAN_BUILD_DIR:-build-asan}
SAN=${REFDYN_SANITIZE:-address,undefined}
JOBS=${JOBS:-$(nproc)}
CXX_SAN=${SANITIZER_CXX:-clang++-14}
CC_SAN=${SANITIZER_CC:-clang-14}
FUZZ=OFF
if [[ "$CXX_SAN" == clang* && "$SAN" == *address* ]]; then FUZZ=ON; fi
bash scripts/configure.sh "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1" -DCMAKE_CXX_COMPILER="$CXX_SAN" -DCMAKE_C_COMPILER="$CC_SAN" \
  -DREFDYN_SANITIZE="$SAN" -DREFDYN_FUZZ=$FUZZ
cmake --build "$BUILD_DIR" -j "$JOBS"
# halt_on_error: the first report ends the test (non-zero exit); leaks are reports too.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:strict_string_checks=1:check_initialization_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
cd "$BUILD_DIR"
# Tests labelled not_sanitized run no refdyn code of their own (a Python script on synthetic data, a
# browser on the report): they run in the normal suite only. So do install_consumer (the installed
# package built and linked by a consumer: packaging, checked by the normal suite) and nine of the
# ten hostile folder names of plot_test (matplotlib's time; refdyn's own part, the argument vector
# of the child process, is the same for all ten and one of them runs here). docs/testing.md,
# "CI time".
# Eight numeric cases run in the normal suite only: each took 25-133 s here (clang ASan, 486
# CPU-seconds together, a third of the stage's test time) and checks optimizer and sensitivity
# numbers; the same code runs under the sanitizers in the other cases of optimize_test and
# sensitivity_test (docs/testing.md, "CI time").
NUMERIC_CASES='OptimizePaperDuration\.OptimumFeasibleOnePercentLessNotAndSweepAgrees|OptimizeGradient\.SlsqpAgreesWithCobyla'
NUMERIC_CASES+='|OptimizeEvaluations\.EachPointPlannedOnceAndRowsComplete|OptimizeMethods\.BobyqaWithConstraintsRunsUnderAuglag'
NUMERIC_CASES+='|Sensitivity\.(PaperDriveDurationAndHeightLawAgreeWithCentralDifferences|NonholonomicUnicycleSpeedAndDampingAgree'
NUMERIC_CASES+='|UnderATimeLawEveryParameterSubsetGivesTheSameColumns|TheRetimedCircleMatchesTheClosedFormAloneAndInSubsets)'
ctest --output-on-failure -j "$JOBS" -LE not_sanitized \
  -E "^install_consumer\$|^Plot/HostileFolderName\.[A-Za-z]+/(leading_dash|leading_double_dash|backslash_dollar|pipe_and_ampersand|parent_folder_payload|newline|single_quotes|double_quotes|backticks)( |\$)|^(${NUMERIC_CASES})\$"
