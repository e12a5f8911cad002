#!/usr/bin/env bash
# Configures and builds the native core, its unit tests and the Python module
# (python/smoothffd/_core*.so, built for Debian's /usr/bin/python3 = Blender 3.4's Python).
# The CUDA backend is built whenever nvcc is found (/usr/local/cuda/bin is searched too).
# SMOOTHFFD_TESTS=OFF leaves out the GoogleTest unit tests (scripts/setup.sh --demo); the value
# is passed on every run, so a later default build brings them back into the same build/.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
PY=${PYTHON:-/usr/bin/python3}
[ -x "$PY" ] || PY=$(command -v python3)
export PATH="$PATH:/usr/local/cuda/bin"
extra=(-DSMOOTHFFD_TESTS="${SMOOTHFFD_TESTS:-ON}")
if command -v nvcc >/dev/null 2>&1; then
  extra+=(-DSMOOTHFFD_CUDA=ON -DCMAKE_CUDA_COMPILER="$(command -v nvcc)")
fi
pyb=$("$PY" -c 'import pybind11; print(pybind11.get_cmake_dir())' 2>/dev/null || true)
[ -n "$pyb" ] && extra+=(-Dpybind11_DIR="$pyb")
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$PY" "${extra[@]}" ${CMAKE_ARGS:-} >/dev/null
cmake --build "$BUILD_DIR" -j"$(nproc)"
