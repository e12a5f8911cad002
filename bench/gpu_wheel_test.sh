#!/usr/bin/env bash
# The shipped Linux x86-64 wheel on a GPU machine (an H100 with CUDA 13 and a driver for it,
# CPython 3.12 with numpy and pytest, no package registry needed): dist/'s cp312 wheel,
# the very file scripts/package.sh made, is installed into /tmp/site and the suites run from
# outside the source tree:
#   on the build machine:  bash bench/gpu_wheel_test.sh prep    (after scripts/package.sh;
#                          copies the wheel to .devwheel/, which git ignores)
#   on the GPU machine:    bash bench/gpu_wheel_test.sh run     (in a copy of the checkout
#                          that has .devwheel/)
# `run` writes its logs to $OUT (default /tmp/out): the whole non-Blender suite, the GPU
# suites again with CUDA_FORCE_PTX_JIT=1 (the path GPUs newer than the built architectures
# take), and W1.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${1:-}" in
prep)
    set -e
    wheel=$(ls "$ROOT"/dist/smoothffd-*-cp312-cp312-manylinux_2_28_x86_64.whl 2>/dev/null | head -1)
    [ -n "$wheel" ] || { echo "prep: run scripts/package.sh first" >&2; exit 1; }
    rm -rf "$ROOT/.devwheel"; mkdir -p "$ROOT/.devwheel"
    cp "$wheel" "$ROOT/.devwheel/"
    grep -qx '/.devwheel/' "$ROOT/.git/info/exclude" || echo '/.devwheel/' >> "$ROOT/.git/info/exclude"
    ls -l "$ROOT/.devwheel" ;;
run)
    cd "$ROOT"
    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .devwheel/*.whl || exit 1
    export PYTHONPATH=/tmp/site SMOOTHFFD_TEST_INSTALLED=1 PYTHONUNBUFFERED=1
    OUT="${OUT:-/tmp/out}"; mkdir -p "$OUT"
    nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv | tee "$OUT/gpu.txt"
    (cd /tmp && python3 -c 'import smoothffd, smoothffd._core as c; print(smoothffd.__file__, c.cpu_isa(), smoothffd.cuda_status())') | tee -a "$OUT/gpu.txt"
    ign=(--ignore="$ROOT/tests/test_blender.py" --ignore="$ROOT/tests/test_scenes.py" --ignore="$ROOT/tests/test_packaging.py"
         --ignore="$ROOT/tests/test_platforms.py" --ignore="$ROOT/tests/blender")
    (cd /tmp && python3 -m pytest -q -ra -p no:cacheprovider "$ROOT/tests" "${ign[@]}") > "$OUT/pytest_all.txt" 2>&1
    echo "all: $(tail -1 "$OUT/pytest_all.txt")"
    (cd /tmp && CUDA_FORCE_PTX_JIT=1 python3 -m pytest -q -ra -p no:cacheprovider "$ROOT/tests/test_cuda.py" \
        "$ROOT/tests/test_cuda_optional.py") > "$OUT/pytest_ptx_jit.txt" 2>&1
    echo "PTX JIT: $(tail -1 "$OUT/pytest_ptx_jit.txt")"
    (cd /tmp && python3 "$ROOT/bench/bench_gpu.py" --quick --out "$OUT/w1.json") > "$OUT/w1.txt" 2>&1
    tail -25 "$OUT/w1.txt" ;;
*) sed -n '2,10p' "$0"; exit 2 ;;
esac
