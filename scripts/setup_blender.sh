#!/usr/bin/env bash
# Installs the Blenders the add-on tests run in, idempotently (each step is skipped when done,
# so scripts/test.sh calls this every time):
#   blender-3.4  Debian's Blender 3.4.1 (apt) for `blender -b` runs;
#   bpy-4.2      PyPI bpy, newest 4.2.x LTS (cp311)  in $CACHE/venv-bpy-4.2
#   bpy-4.5      PyPI bpy, newest 4.5.x LTS (cp311)  in $CACHE/venv-bpy-4.5
#   bpy-5.0      PyPI bpy 5.0.1 (cp311)              in $CACHE/venv-bpy-5.0
#   bpy-5.1      PyPI bpy 5.1.0 (cp313 only): a Debian 13 (trixie) chroot $CACHE/trixie with
#                python3.13 and the tools to build the core for it (g++, cmake, Eigen,
#                python3.13-dev, pybind11), and in it the venv /opt/venv-bpy-5.1; commands run
#                in it through scripts/py313.sh.
# $CACHE is ${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}: outside the repository, so fresh clones
# (CI) reuse it. Each environment is marked done by a stamp file written last, so an
# interrupted step is redone from scratch. Needs root (apt, debootstrap, chroot) or sudo.
# Options: --only NAME[,NAME...] sets up only those (names as above); SMOOTHFFD_SKIP_BLENDERS=
# "bpy-5.1 ..." skips some.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive

# Exact pins (newest of each LTS line on PyPI when this was written; `pip index versions bpy`
# from a Python 3.11 lists them). numpy: bpy 4.5, 5.0 and 5.1 declare "numpy<2.0,>=1.26" in
# their METADATA, 4.2 just "numpy" (it was built with 1.x): numpy<2 everywhere. numpy 1.26 has
# no cp313 wheel, so for 5.1 pip builds it from source once (minutes; the chroot's pip cache
# keeps the wheel).
declare -A BPY_VERSION=([bpy-4.2]=4.2.23 [bpy-4.5]=4.5.15 [bpy-5.0]=5.0.1 [bpy-5.1]=5.1.0)
declare -A NUMPY_SPEC=([bpy-4.2]='numpy<2' [bpy-4.5]='numpy<2' [bpy-5.0]='numpy<2' [bpy-5.1]='numpy<2')
ALL="blender-3.4 bpy-4.2 bpy-4.5 bpy-5.0 bpy-5.1"
ONLY="$ALL"
if [ "${1:-}" = "--only" ]; then ONLY="${2//,/ }"; fi
wanted() {
    case " $ONLY " in *" $1 "*) ;; *) return 1 ;; esac
    case " ${SMOOTHFFD_SKIP_BLENDERS:-} " in *" $1 "*) echo "setup_blender: $1 skipped (SMOOTHFFD_SKIP_BLENDERS)"; return 1 ;; esac
}
mkdir -p "$CACHE"
# One setup at a time (two CI runs may start together).
exec 8>"$CACHE/.setup.lock"
flock 8
timed() {   # timed LABEL CMD...: runs CMD, prints how long it took
    local label="$1" t0=$SECONDS
    shift
    "$@"
    echo "setup_blender: $label took $((SECONDS - t0)) s"
}

# --- Debian's Blender 3.4.1 -----------------------------------------------------------------
setup_debian_blender() {
    $SUDO apt-get update
    # python3-numpy: Debian's Blender uses the system Python, whose numpy the add-on needs.
    $SUDO apt-get install -y --no-install-recommends blender python3-numpy
}
if wanted blender-3.4 && ! { command -v blender >/dev/null && /usr/bin/python3 -c 'import numpy' 2>/dev/null; }; then
    timed blender-3.4 setup_debian_blender
fi

# --- cp311 venvs: bpy 4.2, 4.5, 5.0 ---------------------------------------------------------
PY311="${PYTHON311:-/usr/bin/python3}"
if ! "$PY311" -c 'import sys, venv; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
    if command -v python3.11 >/dev/null; then PY311=python3.11; else PY311=""; fi
fi
setup_venv() {   # setup_venv NAME
    local venv="$CACHE/venv-$1" ver="${BPY_VERSION[$1]}"
    "$PY311" -m venv "$venv"   # keeps what an earlier, interrupted try installed
    "$venv/bin/python" -m pip install -q --disable-pip-version-check "bpy==$ver" "${NUMPY_SPEC[$1]}"
    "$venv/bin/python" -c 'import bpy, numpy; print("setup_blender:", bpy.app.version_string, "numpy", numpy.__version__)'
    touch "$venv/.smoothffd-done-$ver"
}
for name in bpy-4.2 bpy-4.5 bpy-5.0; do
    wanted "$name" || continue
    [ -e "$CACHE/venv-$name/.smoothffd-done-${BPY_VERSION[$name]}" ] && continue
    if [ -z "$PY311" ]; then
        echo "setup_blender: no Python 3.11 for $name (apt-get install python3 python3-venv, or" \
             "PYTHON311=/path/to/python3.11; SMOOTHFFD_SKIP_BLENDERS=\"$name\" leaves it out)" >&2
        exit 1
    fi
    if ! "$PY311" -c 'import ensurepip' 2>/dev/null; then
        $SUDO apt-get install -y --no-install-recommends python3-venv
    fi
    timed "$name" setup_venv "$name"
done

# --- Debian 13 chroot with Python 3.13: bpy 5.1 and the tools to build the core for it -------
CHROOT="$CACHE/trixie"
CHROOT_VENV=/opt/venv-bpy-5.1
# Python 3.13 and the tools to build the core for it; the X11/GL libraries bpy links to.
TRIXIE_PACKAGES="python3.13 python3.13-venv python3.13-dev python3-pip python3-venv g++ cmake make ninja-build libeigen3-dev git ca-certificates libx11-6 libxext6 libxrender1 libxfixes3 libxi6 libxxf86vm1 libxkbcommon0 libsm6 libice6 libgl1 libegl1"
setup_chroot() {
    if [ -d "$CHROOT" ]; then
        # An interrupted earlier try: nothing may still be mounted in it before it is removed.
        if grep -q " $CHROOT/" /proc/mounts; then
            echo "setup_blender: $CHROOT has mounts (a py313.sh still running?); not touching it" >&2
            return 1
        fi
        $SUDO rm -rf --one-file-system "$CHROOT"
    fi
    command -v debootstrap >/dev/null || $SUDO apt-get install -y --no-install-recommends debootstrap
    $SUDO debootstrap --variant=minbase trixie "$CHROOT" http://deb.debian.org/debian
    $SUDO cp /etc/resolv.conf "$CHROOT/etc/resolv.conf" 2>/dev/null || true
    $SUDO touch "$CHROOT/.smoothffd-chroot-done"
}
setup_chroot_packages() {   # again whenever the list changes
    SMOOTHFFD_CHROOT="$CHROOT" bash "$ROOT/scripts/py313.sh" sh -c \
        "apt-get update && apt-get install -y --no-install-recommends $TRIXIE_PACKAGES && apt-get clean"
    echo "$TRIXIE_PACKAGES" | $SUDO tee "$CHROOT/.smoothffd-packages" >/dev/null
}
setup_venv313() {
    local ver="${BPY_VERSION[bpy-5.1]}"
    # Certificate authorities this machine adds (an HTTPS proxy's, say) must be trusted in
    # the chroot too, or pip cannot reach PyPI.
    if compgen -G "/usr/local/share/ca-certificates/*" >/dev/null; then
        $SUDO mkdir -p "$CHROOT/usr/local/share/ca-certificates"
        $SUDO cp -r /usr/local/share/ca-certificates/. "$CHROOT/usr/local/share/ca-certificates/"
        SMOOTHFFD_CHROOT="$CHROOT" bash "$ROOT/scripts/py313.sh" update-ca-certificates >/dev/null
    fi
    SMOOTHFFD_CHROOT="$CHROOT" bash "$ROOT/scripts/py313.sh" sh -c "
        set -e; python3.13 -m venv $CHROOT_VENV
        $CHROOT_VENV/bin/python -m pip install -q --disable-pip-version-check \
            'bpy==$ver' '${NUMPY_SPEC[bpy-5.1]}' 'pybind11>=2.13' scikit-build-core build
        $CHROOT_VENV/bin/python -c 'import bpy, numpy; print(\"setup_blender:\", bpy.app.version_string, \"numpy\", numpy.__version__)'
        touch $CHROOT_VENV/.smoothffd-done-$ver"
}
if wanted bpy-5.1; then
    if [ ! -e "$CHROOT/.smoothffd-chroot-done" ]; then timed "trixie chroot" setup_chroot; fi
    if [ "$(cat "$CHROOT/.smoothffd-packages" 2>/dev/null)" != "$TRIXIE_PACKAGES" ]; then
        timed "trixie packages" setup_chroot_packages
    fi
    if [ ! -e "$CHROOT$CHROOT_VENV/.smoothffd-done-${BPY_VERSION[bpy-5.1]}" ]; then timed bpy-5.1 setup_venv313; fi
fi
echo "setup_blender: done (cache $CACHE)"
