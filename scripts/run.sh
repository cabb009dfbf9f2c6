#!/usr/bin/env bash
# Builds everything and runs the main job: the paper's three-link manipulator study.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$(nproc)"
"$BUILD_DIR/apps/refdyn" paper --output "${OUTPUT_DIR:-results}" "$@"
