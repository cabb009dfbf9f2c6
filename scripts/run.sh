#!/usr/bin/env bash
# Builds everything and runs the main job: the paper's three-link manipulator study
# (plan + 8 closed loops), writing CSV/JSON results, figures (PNG + PDF) and report.html (one
# self-contained page: summary, interactive plots, 3D replay; docs/report.md) into results/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD_DIR=${BUILD_DIR:-build}
OUT=${OUTPUT_DIR:-results}
bash scripts/configure.sh "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$(nproc)"
"$BUILD_DIR/apps/refdyn" paper --output "$OUT" --report
/usr/bin/python3 scripts/plot_study.py "$OUT"
