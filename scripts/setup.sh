#!/usr/bin/env bash
# Installs what the build and the tests need on Debian 12 (idempotent), then builds.
# Usage: scripts/setup.sh            (apt packages + build, unit tests included)
#        scripts/setup.sh --demo     (only what scripts/demo.sh uses: the compilers, Eigen,
#                                     pybind11, numpy and matplotlib; the CPU build of the
#                                     Python module, without the unit tests or CUDA)
set -euo pipefail
cd "$(dirname "$0")/.."

# The core and its Python module, and blender_scenes/composite.py's matplotlib.
need=(cmake g++ make pybind11-dev libeigen3-dev python3-dev python3-numpy python3-matplotlib)
if [ "${1:-}" = "--demo" ]; then
  # The demo renders on the CPU: no CUDA backend (a later plain setup.sh adds it back where
  # nvcc is found, and the unit tests).
  export SMOOTHFFD_TESTS=OFF CMAKE_ARGS="${CMAKE_ARGS:-} -DSMOOTHFFD_CUDA=OFF"
else
  # python3-venv: scripts/package.sh and the tests' fresh venvs; qemu-user: the wheels run under
  # emulated older CPUs (tests/test_isa.py); binutils: readelf/objdump for the artefact checks;
  # clang and its runtime: the fuzzers.
  need+=(binutils python3-venv python3-pytest libgtest-dev clang libclang-rt-14-dev qemu-user)
fi
missing=()
for p in "${need[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
bash scripts/build.sh
