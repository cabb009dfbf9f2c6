#!/usr/bin/env bash
# Configures a build folder: `bash scripts/configure.sh DIR [cmake options...]`.
# A new folder gets the Ninja generator (scripts/install-deps.sh installs ninja-build): Ninja
# starts compiling a target's sources as soon as their own inputs exist, where Make waits for
# every library the target links, which left one of the two cores idle at the end of each
# library (docs/testing.md, "CI time"). A folder configured before keeps its generator (CMake
# refuses to switch one), so an existing build/ goes on working.
set -euo pipefail
dir=$1
shift
gen=()
if [[ ! -f "$dir/CMakeCache.txt" ]] && command -v ninja > /dev/null; then gen=(-G Ninja); fi
cmake -S . -B "$dir" "${gen[@]}" "$@"
