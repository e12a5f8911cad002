#!/usr/bin/env bash
# Installs what the Blender add-on tests need, idempotently:
#   1. Debian's Blender (3.4.1 on bookworm) for `blender -b` runs;
#   2. a venv build/venv-bpy with PyPI `bpy` (Blender as a Python module, >= 4.5 LTS) and numpy<2.
# Each step is skipped when it is already done, so the test script may call this every time.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/build/venv-bpy"
# bpy publishes a wheel for exactly one CPython per release; 4.5 LTS and 5.0 are cp311.
BPY_SPEC="${SMOOTHFFD_BPY_SPEC:-bpy>=4.5,<5.1}"

if ! command -v blender >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update
    # python3-numpy: Debian's Blender uses the system Python, whose numpy the add-on needs.
    $SUDO apt-get install -y --no-install-recommends blender python3-numpy
fi

PY="${PYTHON311:-python3}"
if ! "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
    # Only a cp311 interpreter can load the bpy wheel.
    if command -v python3.11 >/dev/null 2>&1; then PY=python3.11
    else echo "setup_blender: no Python 3.11 found; bpy venv not created" >&2; exit 0; fi
fi

if [ ! -x "$VENV/bin/python" ]; then
    "$PY" -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c 'import bpy, numpy' >/dev/null 2>&1; then
    "$VENV/bin/python" -m pip install --upgrade "$BPY_SPEC" 'numpy<2' pytest
fi
"$VENV/bin/python" -c 'import bpy, numpy; print("setup_blender: bpy", bpy.app.version_string, "numpy", numpy.__version__)'
