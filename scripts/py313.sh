#!/usr/bin/env bash
# Runs a command inside the Debian 13 (trixie) chroot made by scripts/setup_blender.sh, which has
# Python 3.13 (bpy 5.1 is cp313 only), the venv /opt/venv-bpy-5.1 and the tools to build the
# core for 3.13. Examples:
#   bash scripts/py313.sh python3.13 -c 'import sys; print(sys.version)'
#   bash scripts/py313.sh /opt/venv-bpy-5.1/bin/python tests/blender/check_parity.py
# The working directory, the environment and the exit status carry over. /proc, /dev, /sys,
# /tmp and the repository are mounted in the chroot at the same paths (so paths given on the
# command line mean the same inside), in a private mount namespace (unshare) when the kernel
# allows it, so nothing leaks to the host and concurrent runs do not disturb each other; the
# mounts are also undone on exit (trap). Needs root or sudo.
# --host-toolchain (first argument): compile with THIS machine's compiler and libraries instead
# of trixie's (scripts/package.sh builds the cp313 wheel so): the host's /usr is mounted
# read-only at /host/usr and CC/CXX/CFLAGS/CXXFLAGS/LDFLAGS point at its g++ with
# --sysroot=/host (trixie's binutils, ar and strip: the host's need their own libbfd), so the module needs no newer glibc or libstdc++ than Debian 12 has; only
# Python 3.13's own headers come from trixie.
# SMOOTHFFD_CHROOT overrides the chroot's path (default ${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}/trixie).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CHROOT="${SMOOTHFFD_CHROOT:-${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}/trixie}"
if [ $# -eq 0 ]; then echo "usage: py313.sh COMMAND [ARGS...]" >&2; exit 2; fi
if [ ! -x "$CHROOT/bin/sh" ]; then
    echo "py313.sh: no chroot at $CHROOT (run scripts/setup_blender.sh)" >&2; exit 3
fi
if [ "$(id -u)" -ne 0 ]; then exec sudo --preserve-env bash "$0" "$@"; fi

# Enter a private mount namespace once (the mounts below then vanish with this process).
if [ -z "${_PY313_NS:-}" ] && unshare --mount --propagation private true 2>/dev/null; then
    export _PY313_NS=1
    exec unshare --mount --propagation private bash "$0" "$@"
fi

MOUNTED=()
cleanup() {
    local i
    for ((i = ${#MOUNTED[@]} - 1; i >= 0; i--)); do
        umount "${MOUNTED[$i]}" 2>/dev/null || umount -l "${MOUNTED[$i]}" 2>/dev/null || true
    done
}
trap cleanup EXIT
trap 'exit 130' INT TERM

bind() {   # bind SRC [TYPE]: SRC at the same path in the chroot, unless it is already there
    local src="$1" dst="$CHROOT$1"
    if [ -d "$dst" ] && [ "$src" -ef "$dst" ]; then return 0; fi   # already visible
    mkdir -p "$dst"
    if [ "${2:-}" = proc ]; then
        mount -t proc proc "$dst"
    else
        mount --bind "$src" "$dst"
    fi
    MOUNTED+=("$dst")
}
# Order matters: /tmp before the repository, which may live under /tmp (a clone in mktemp -d):
# then it is already visible through /tmp and is not mounted again.
bind /proc proc
bind /dev
bind /dev/pts
bind /sys
bind /tmp
bind "$ROOT"
WD="$PWD"
[ -d "$CHROOT$WD" ] && [ "$WD" -ef "$CHROOT$WD" ] || WD="$ROOT"

TOOLCHAIN=()
if [ "${1:-}" = "--host-toolchain" ]; then
    shift
    mkdir -p "$CHROOT/host/usr"
    mount --bind /usr "$CHROOT/host/usr" && MOUNTED+=("$CHROOT/host/usr")
    mount -o remount,bind,ro "$CHROOT/host/usr" 2>/dev/null || true
    for d in lib bin sbin; do [ -e "$CHROOT/host/$d" ] || ln -s "usr/$d" "$CHROOT/host/$d"; done
    # The host's /lib64/ld-linux-x86-64.so.2 is an absolute link, which would name trixie's
    # loader in the chroot: give the sysroot its own pointing at the host's.
    mkdir -p "$CHROOT/host/lib64"
    ln -sfn /host/usr/lib/x86_64-linux-gnu/ld-linux-x86-64.so.2 "$CHROOT/host/lib64/ld-linux-x86-64.so.2"
    # Debian's Python.h includes <x86_64-linux-gnu/python3.13/pyconfig.h>: expose that one
    # folder of trixie's after the sysroot's own headers.
    mkdir -p "$CHROOT/opt/pyinc/x86_64-linux-gnu"
    ln -sfn /usr/include/x86_64-linux-gnu/python3.13 "$CHROOT/opt/pyinc/x86_64-linux-gnu/python3.13"
    gxx=$(readlink -f /usr/bin/g++); gcc=$(readlink -f /usr/bin/gcc)
    TOOLCHAIN=(CC="/host$gcc" CXX="/host$gxx" CFLAGS="--sysroot=/host -idirafter /opt/pyinc"
               CXXFLAGS="--sysroot=/host -idirafter /opt/pyinc" LDFLAGS="--sysroot=/host"
               CMAKE_ARGS="-DCMAKE_AR=/usr/bin/ar -DCMAKE_RANLIB=/usr/bin/ranlib -DCMAKE_STRIP=/usr/bin/strip -DCMAKE_NM=/usr/bin/nm -DCMAKE_OBJCOPY=/usr/bin/objcopy -DCMAKE_OBJDUMP=/usr/bin/objdump")
fi

# Not exec: the trap must run after the command.
set +e
env -u _PY313_NS chroot "$CHROOT" /usr/bin/env \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/root "${TOOLCHAIN[@]}" \
    sh -c 'cd "$1" && shift && exec "$@"' sh "$WD" "$@"
rc=$?
exit $rc
