#!/usr/bin/env bash
# Installs every Debian package refdyn needs to build, test, benchmark, plot and fuzz
# (ninja-build: the generator of new build folders, scripts/configure.sh;
# clang-14 + libclang-rt-14-dev: libFuzzer and sanitizer runtimes; llvm-14: llvm-symbolizer;
# texlive-latex-base: pdflatex, which tests/symbolic_test uses to compile the generated LaTeX;
# libjs-three + libjs-dygraphs: the JavaScript libraries inlined into report.html at build time;
# chromium + python3-pil: the report's browser test, tests/report_browser_test.py;
# nlohmann-json3-dev: JSON values, reading and writing (common/json.hpp);
# libkdl-parser-dev: KDL's URDF reader, the URDF cross-check of bench/dynamics_bench.cpp;
# libnlopt-cxx-dev: NLopt, the optimizers of `refdyn optimize` (optimize/optimize.hpp);
# libsundials-dev: CVODES, the implicit BDF integrator for stiff problems (simulate/bdf.hpp);
# libopenmpi-dev + openmpi-bin: `refdyn track --mpi` and its test, tests/mpi_test.sh).
# Idempotent: when everything is present it only runs dpkg-query and returns.
set -euo pipefail
PACKAGES=(
  cmake g++ make ninja-build pkg-config
  libeigen3-dev libboost-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev libcli11-dev libginac-dev nlohmann-json3-dev libsundials-dev
  liburdfdom-dev liborocos-kdl-dev libkdl-parser-dev libmujoco-dev libnlopt-cxx-dev
  python3 python3-matplotlib
  clang-14 libclang-rt-14-dev llvm-14
  pybind11-dev python3-dev python3-numpy python3-pytest python3-yaml
  texlive-latex-base
  libjs-three libjs-dygraphs chromium python3-pil
  libopenmpi-dev openmpi-bin
)
missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
