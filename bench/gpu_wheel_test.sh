#!/usr/bin/env bash
# The shipped package on a real GPU (issue "Install anywhere"): the lent machine has CPython
# 3.12 and no package registry, so a cp312 wheel is made here from the same sources with the
# very CUDA library of dist/'s wheels, carried in .devwheel/, installed there into /tmp/site
# and tested from outside the tree:
#   here:  bash bench/device_wheel_test.sh prep [PYTHON3.12]   (after scripts/package.sh)
#   there: bash bench/device_wheel_test.sh run                 (device tool, carry .devwheel)
# `run` writes its logs to $OUT: the whole non-Blender suite, the GPU suites again with
# CUDA_FORCE_PTX_JIT=1 (the path GPUs newer than the built architectures take), and W1.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${1:-}" in
prep)
    set -e
    PY="${2:-$HOME/.pyenv/versions/3.12.1/bin/python}"
    CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
    lib="$ROOT/build/package/libsmoothffd_cuda.so"   # scripts/package.sh leaves it there
    [ -f "$lib" ] || { echo "prep: run scripts/package.sh first" >&2; exit 1; }
    "$PY" -m venv "$CACHE/venv-build312"
    "$CACHE/venv-build312/bin/pip" install -q --upgrade pip
    rm -rf "$ROOT/.devwheel" "$ROOT/build/package/raw312"
    "$CACHE/venv-build312/bin/pip" wheel "$ROOT" --no-deps -q -w "$ROOT/build/package/raw312" \
        -C build-dir=build/skbuild/cp312 -C cmake.define.SMOOTHFFD_CUDA=OFF \
        -C cmake.define.SMOOTHFFD_CUDA_PREBUILT="$lib"
    PATH="$CACHE/venv-package/bin:$PATH" auditwheel repair --plat manylinux_2_34_x86_64 \
        -w "$ROOT/.devwheel" "$ROOT"/build/package/raw312/*.whl
    grep -qx '/.devwheel/' "$ROOT/.git/info/exclude" || echo '/.devwheel/' >> "$ROOT/.git/info/exclude"
    ls -l "$ROOT/.devwheel" ;;
run)
    cd "$ROOT"
    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .devwheel/*.whl || exit 1
    export PYTHONPATH=/tmp/site SMOOTHFFD_TEST_INSTALLED=1 PYTHONUNBUFFERED=1
    OUT="${OUT:-/tmp/out}"; mkdir -p "$OUT"
    nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv | tee "$OUT/gpu.txt"
    (cd /tmp && python3 -c 'import smoothffd, smoothffd._core as c; print(smoothffd.__file__, c.cpu_isa(), smoothffd.cuda_status())') | tee -a "$OUT/gpu.txt"
    ign=(--ignore="$ROOT/tests/test_blender.py" --ignore="$ROOT/tests/test_scenes.py" --ignore="$ROOT/tests/test_packaging.py")
    (cd /tmp && python3 -m pytest -q -ra -p no:cacheprovider "$ROOT/tests" "${ign[@]}") > "$OUT/pytest_all.txt" 2>&1
    echo "all: $(tail -1 "$OUT/pytest_all.txt")"
    (cd /tmp && CUDA_FORCE_PTX_JIT=1 python3 -m pytest -q -ra -p no:cacheprovider "$ROOT/tests/test_cuda.py" \
        "$ROOT/tests/test_cuda_optional.py") > "$OUT/pytest_ptx_jit.txt" 2>&1
    echo "PTX JIT: $(tail -1 "$OUT/pytest_ptx_jit.txt")"
    (cd /tmp && python3 "$ROOT/bench/bench_gpu.py" --quick --out "$OUT/w1.json") > "$OUT/w1.txt" 2>&1
    tail -25 "$OUT/w1.txt" ;;
*) sed -n '2,10p' "$0"; exit 2 ;;
esac
