#!/usr/bin/env bash
# Builds the core's Python module for CPython 3.13 (bpy 5.1) inside the trixie chroot
# (scripts/setup_blender.sh makes it; scripts/py313.sh enters it): CPU backend only, no unit
# tests, build folder build/py313, and the module lands in python/smoothffd/ as
# _core.cpython-313-*.so beside the cp311 one. Skipped when that module is newer than every
# native source. For development; shipped builds are wheels (scripts/package.sh).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV=/opt/venv-bpy-5.1
shopt -s nullglob
so=(python/smoothffd/_core.cpython-313-*.so)
if [ ${#so[@]} -gt 0 ] && [ -z "$(find native CMakeLists.txt -newer "${so[0]}" -type f -print -quit)" ]; then
    echo "build_py313: ${so[0]} is up to date"; exit 0
fi
# This machine's g++ and libraries (--host-toolchain), as for the shipped cp313 wheel.
bash scripts/py313.sh --host-toolchain sh -c "
    set -e
    cmake -S . -B build/py313 -DCMAKE_BUILD_TYPE=Release -DSMOOTHFFD_CUDA=OFF -DSMOOTHFFD_TESTS=OFF \
        -DPython_EXECUTABLE=/usr/bin/python3.13 \
        -Dpybind11_DIR=\$($VENV/bin/python -m pybind11 --cmakedir) \$CMAKE_ARGS >/dev/null
    cmake --build build/py313 -j$(nproc)"
ls python/smoothffd/_core.cpython-313-*.so
