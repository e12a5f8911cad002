#!/usr/bin/env bash
# The shipped Linux x86-64 wheel on a GPU machine (an H100 or H200 with CUDA 13 and a driver for
# it, CPython 3.12 with numpy and pytest, no package registry needed): dist/'s cp312 wheel,
# the very file scripts/package.sh made, is installed into /tmp/site and the suites run from
# outside the source tree:
#   on the build machine:  bash bench/gpu_wheel_test.sh prep    (after scripts/package.sh;
#                          copies the wheel to .devwheel/, which git ignores)
#                          bash bench/gpu_wheel_test.sh baseline WHEEL REV   (optional: an
#                          earlier cp312 wheel and the bench/bench_gpu.py of the commit REV it
#                          was built from, to .devwheel/baseline/)
#   on the GPU machine:    bash bench/gpu_wheel_test.sh run [--all]   (in a copy of the
#                          checkout that has .devwheel/)
# `run` writes its logs to $OUT (default /tmp/out): the GPU suites and the core's first suite
# (--all: the whole non-Blender suite, and the GPU suites again with CUDA_FORCE_PTX_JIT=1, the
# path GPUs newer than the built architectures take), then W1 at level 10
# (bench/bench_gpu.py --quick); with a baseline, W1 of the baseline wheel before and after it,
# in the same run.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
GPU_SUITES=(test_cuda.py test_cuda_optional.py test_cuda_real_meshes.py test_compact.py test_positions_only.py
            test_deform_basics.py)
case "${1:-}" in
prep)
    set -e
    wheel=$(ls "$ROOT"/dist/smoothffd-*-cp312-cp312-manylinux_2_28_x86_64.whl 2>/dev/null | head -1)
    [ -n "$wheel" ] || { echo "prep: run scripts/package.sh first" >&2; exit 1; }
    mkdir -p "$ROOT/.devwheel"; rm -f "$ROOT"/.devwheel/*.whl
    cp "$wheel" "$ROOT/.devwheel/"
    grep -qx '/.devwheel/' "$ROOT/.git/info/exclude" || echo '/.devwheel/' >> "$ROOT/.git/info/exclude"
    ls -lR "$ROOT/.devwheel" ;;
baseline)
    set -e
    [ $# -eq 3 ] || { echo "usage: $0 baseline WHEEL REV" >&2; exit 2; }
    rm -rf "$ROOT/.devwheel/baseline"; mkdir -p "$ROOT/.devwheel/baseline"
    cp "$2" "$ROOT/.devwheel/baseline/"
    git -C "$ROOT" show "$3:bench/bench_gpu.py" > "$ROOT/.devwheel/baseline/bench_gpu.py"
    echo "$3" > "$ROOT/.devwheel/baseline/REV"
    grep -qx '/.devwheel/' "$ROOT/.git/info/exclude" || echo '/.devwheel/' >> "$ROOT/.git/info/exclude"
    ls -l "$ROOT/.devwheel/baseline" ;;
run)
    cd "$ROOT"
    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .devwheel/*.whl || exit 1
    export SMOOTHFFD_TEST_INSTALLED=1 PYTHONUNBUFFERED=1
    OUT="${OUT:-/tmp/out}"; mkdir -p "$OUT"
    nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv | tee "$OUT/gpu.txt"
    (cd /tmp && PYTHONPATH=/tmp/site python3 -c 'import smoothffd, smoothffd._core as c; print(smoothffd.__file__, c.cpu_isa(), smoothffd.cuda_status())') | tee -a "$OUT/gpu.txt"
    if [ "${2:-}" = "--all" ]; then
        ign=(--ignore="$ROOT/tests/test_blender.py" --ignore="$ROOT/tests/test_scenes.py" --ignore="$ROOT/tests/test_packaging.py"
             --ignore="$ROOT/tests/test_platforms.py" --ignore="$ROOT/tests/blender")
        (cd /tmp && PYTHONPATH=/tmp/site python3 -m pytest -q -ra -p no:cacheprovider "$ROOT/tests" "${ign[@]}") > "$OUT/pytest.txt" 2>&1
    else
        (cd /tmp && PYTHONPATH=/tmp/site python3 -m pytest -q -ra -p no:cacheprovider "${GPU_SUITES[@]/#/$ROOT/tests/}") > "$OUT/pytest.txt" 2>&1
    fi
    echo "pytest: $(tail -1 "$OUT/pytest.txt")"; grep "^CUDA vs CPU" "$OUT/pytest.txt"
    if [ "${2:-}" = "--all" ]; then
        (cd /tmp && CUDA_FORCE_PTX_JIT=1 PYTHONPATH=/tmp/site python3 -m pytest -q -ra -p no:cacheprovider \
            "$ROOT/tests/test_cuda.py" "$ROOT/tests/test_cuda_optional.py") > "$OUT/pytest_ptx_jit.txt" 2>&1
        echo "PTX JIT: $(tail -1 "$OUT/pytest_ptx_jit.txt")"
    fi
    w1() {  # name site bench-script
        (cd /tmp && PYTHONPATH="$2" python3 "$3" --quick --iters 100 --out "$OUT/w1-$1.json") > "$OUT/w1-$1.txt" 2>&1
        echo "== W1 ($1)"; grep -A6 "=== summary" "$OUT/w1-$1.txt" | grep -E "^W1|summary"
    }
    if ls .devwheel/baseline/*.whl >/dev/null 2>&1; then
        python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site-base .devwheel/baseline/*.whl || exit 1
        w1 baseline-1 /tmp/site-base "$ROOT/.devwheel/baseline/bench_gpu.py"
        w1 new /tmp/site "$ROOT/bench/bench_gpu.py"
        w1 baseline-2 /tmp/site-base "$ROOT/.devwheel/baseline/bench_gpu.py"
    else
        w1 new /tmp/site "$ROOT/bench/bench_gpu.py"
    fi ;;
*) sed -n '2,18p' "$0"; exit 2 ;;
esac
