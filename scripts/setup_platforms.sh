#!/usr/bin/env bash
# Installs what running the other platforms' wheels here needs (idempotent; tests/test_platforms.py
# uses it, scripts/test.sh calls this):
#   * Wine (Debian's wine64, 8.0) and, in $CACHE/windows/pythonXY, the Windows CPython 3.10, 3.11
#     and 3.12 of PyPI's QEnvPython3XY (a repackaged embeddable CPython) with its own site folder:
#     numpy 1.26.4 for win_amd64 in its Lib/site-packages (numpy 2.x calls a C-runtime function Wine 8 lacks), pytest
#     and its pure-Python dependencies; PyPI's bpy 4.2 for win_amd64 beside them;
#   * qemu-user (qemu-aarch64) and, in $CACHE/arm64-root, Debian 12's arm64 Python 3.11 with
#     numpy and pytest, unpacked from Debian's own arm64 packages (no binfmt_misc needed: the
#     tests run qemu-aarch64 -L ROOT ROOT/usr/bin/python3.11 explicitly).
set -euo pipefail
cd "$(dirname "$0")/.."
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
need=()
for p in wine64 qemu-user binutils; do dpkg -s "$p" >/dev/null 2>&1 || need+=("$p"); done
if [ ${#need[@]} -gt 0 ]; then
    echo "setup_platforms: installing ${need[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi

# --- Windows CPython under Wine
PIP=(/usr/bin/python3 -m pip download -q --no-deps --only-binary=:all: --disable-pip-version-check)
for v in 3.10 3.11 3.12; do
    tag=${v/./}
    dir="$CACHE/windows/python$tag"
    [ -f "$dir/.complete" ] && continue
    echo "setup_platforms: Windows CPython $v"
    rm -rf "$dir" "$dir.part"; mkdir -p "$dir.part/Lib/site-packages"
    tmp=$(mktemp -d)
    "${PIP[@]}" -d "$tmp" "QEnvPython$tag"
    "${PIP[@]}" -d "$tmp" --platform win_amd64 --python-version "$v" numpy==1.26.4
    "${PIP[@]}" -d "$tmp" --python-version "$v" pytest pluggy iniconfig packaging colorama pygments
    [ "$v" = 3.10 ] && "${PIP[@]}" -d "$tmp" --python-version "$v" exceptiongroup tomli
    /usr/bin/python3 - "$tmp" "$dir.part" "$tag" <<'PY'
import glob, os, sys, zipfile
tmp, dest, tag = sys.argv[1:]
prefix = f"QPT_SDK/QEnvPython/python{tag}/"
for whl in glob.glob(os.path.join(tmp, "*.whl")):
    with zipfile.ZipFile(whl) as z:
        if os.path.basename(whl).lower().startswith("qenvpython"):
            for n in z.namelist():
                if n.startswith(prefix) and not n.endswith("/"):
                    out = os.path.join(dest, n[len(prefix):])
                    os.makedirs(os.path.dirname(out), exist_ok=True)
                    open(out, "wb").write(z.read(n))
        else:
            z.extractall(os.path.join(dest, "Lib", "site-packages"))
# The embeddable CPython's ._pth file fixes sys.path and ignores PYTHONPATH: without it the
# interpreter takes PYTHONPATH and its own Lib/site-packages (where numpy and pytest are),
# as an installed CPython does.
for pth in glob.glob(os.path.join(dest, "*._pth")):
    os.remove(pth)
PY
    rm -rf "$tmp"
    touch "$dir.part/.complete"
    mv "$dir.part" "$dir"
done
# PyPI's bpy 4.2 LTS for Windows (Blender as a Python module, CPython 3.11): the Windows
# extension zip is installed into it under Wine.
BPYWIN="$CACHE/windows/bpy-4.2"
if [ ! -f "$BPYWIN/.complete" ]; then
    echo "setup_platforms: bpy 4.2 for Windows"
    rm -rf "$BPYWIN" "$BPYWIN.part"; mkdir -p "$BPYWIN.part"
    tmp=$(mktemp -d)
    "${PIP[@]}" -d "$tmp" --platform win_amd64 --python-version 3.11 bpy==4.2.23
    /usr/bin/python3 -c 'import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])' "$tmp"/bpy-*.whl "$BPYWIN.part"
    rm -rf "$tmp"
    touch "$BPYWIN.part/.complete"
    mv "$BPYWIN.part" "$BPYWIN"
fi
export WINEPREFIX="$CACHE/wine-prefix" WINEDEBUG=-all
if [ ! -f "$WINEPREFIX/.complete" ]; then
    echo "setup_platforms: Wine prefix"
    /usr/lib/wine/wine64 "$CACHE/windows/python311/python.exe" -c "print('wine ok')" </dev/null 2>&1 | cat  # Wine 8's CPython needs pipes, not files, as its streams
    touch "$WINEPREFIX/.complete"
fi

# --- Debian 12 arm64 root for qemu-aarch64
ROOTFS="$CACHE/arm64-root"
if [ ! -f "$ROOTFS/.complete" ]; then
    echo "setup_platforms: Debian 12 arm64 root"
    rm -rf "$ROOTFS" "$ROOTFS.part"; mkdir -p "$ROOTFS.part"
    lists=$(mktemp -d); mkdir -p "$lists/partial"; chmod -R 777 "$lists"
    o=(-oAPT::Architecture=arm64 -oAPT::Architectures=arm64 -oDir::State::Lists="$lists")
    apt-get "${o[@]}" update -qq
    debs=$(mktemp -d); chmod 777 "$debs"
    (cd "$debs" && apt-get "${o[@]}" download -qq python3.11-minimal libpython3.11-minimal \
        libpython3.11-stdlib libc6 zlib1g libexpat1 libffi8 libssl3 libbz2-1.0 liblzma5 libsqlite3-0 \
        libuuid1 libncursesw6 libtinfo6 libreadline8 libcrypt1 libstdc++6 libgcc-s1 python3-numpy \
        libopenblas0-pthread libgfortran5 liblapack3 libblas3 libopenblas0 python3-pytest \
        python3-pluggy python3-iniconfig python3-packaging python3-attr >/dev/null)
    for f in "$debs"/*.deb; do dpkg -x "$f" "$ROOTFS.part"; done
    # The links update-alternatives would make.
    ln -sf blas/libblas.so.3 "$ROOTFS.part/usr/lib/aarch64-linux-gnu/libblas.so.3"
    ln -sf lapack/liblapack.so.3 "$ROOTFS.part/usr/lib/aarch64-linux-gnu/liblapack.so.3"
    rm -rf "$debs" "$lists"
    qemu-aarch64 -L "$ROOTFS.part" "$ROOTFS.part/usr/bin/python3.11" -c \
        "import sys; sys.path.append('/usr/lib/python3/dist-packages'); import numpy, pytest; print('arm64 python', sys.version.split()[0], 'numpy', numpy.__version__)"
    touch "$ROOTFS.part/.complete"
    mv "$ROOTFS.part" "$ROOTFS"
fi
echo "setup_platforms: ready ($CACHE/windows, $CACHE/arm64-root)"
