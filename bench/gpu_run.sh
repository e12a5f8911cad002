#!/usr/bin/env bash
# On a machine with an NVIDIA GPU and CUDA 13 (nvcc, compute-sanitizer on PATH or in
# /usr/local/cuda/bin): build, GPU tests, compute-sanitizer, benchmark.
#   bash bench/gpu_run.sh
# STEPS (env) picks a subset: "build test sanitize bench" (default: all); PYTEST_X= runs every
# test instead of stopping at the first failure; ARCH_ARG, extra CMake
# arguments (bench/gpu_ab.sh sets it from ARCHS); EIGEN_COPY, a folder with eigen3/ and
# eigen3-cmake/, installs Eigen on a machine without libeigen3-dev. Logs under $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}
mkdir -p "$OUT"
STEPS=${STEPS:-"build test sanitize bench"}
BENCH_ARGS=${BENCH_ARGS:-}
export PATH="$PATH:/usr/local/cuda/bin" PYTHONUNBUFFERED=1 PYTHONPATH="$PWD/python"
has() { [[ " $STEPS " == *" $1 "* ]]; }
{ date -u; nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem,memory.used --format=csv; nvcc --version | tail -1; } > "$OUT/env.txt" 2>&1
cat "$OUT/env.txt"
if has build; then
  if [ -n "${EIGEN_COPY:-}" ]; then  # Eigen copied in, on a machine without libeigen3-dev
    cp -r "$EIGEN_COPY/eigen3" /usr/include/ && mkdir -p /usr/share/eigen3/cmake && cp "$EIGEN_COPY"/eigen3-cmake/* /usr/share/eigen3/cmake/
  fi
  t0=$(date +%s)
  BUILD_DIR=/tmp/sffd-build PYTHON="$(command -v python3)" CMAKE_ARGS="-DSMOOTHFFD_TESTS=OFF ${ARCH_ARG:-}" bash scripts/build.sh > "$OUT/build.log" 2>&1
  rc=$?
  echo "build rc=$rc in $(( $(date +%s) - t0 )) s"; grep -E "error|warning: .*cuda" "$OUT/build.log" | head -20
  [ $rc -eq 0 ] || { tail -30 "$OUT/build.log"; exit 1; }
  cuobjdump --dump-resource-usage python/smoothffd/libsmoothffd_cuda.so > "$OUT/resource_usage.txt" 2>&1 || true
  grep -E "Function|REG|STACK" "$OUT/resource_usage.txt" | head -30
fi
python3 -c "import smoothffd; print(smoothffd.cuda_status())"
if has test; then
  timeout ${TEST_TIMEOUT:-300} python3 -m pytest -q ${PYTEST_X--x} tests/test_cuda.py tests/test_cuda_real_meshes.py tests/test_render_vertices.py tests/test_compact.py \
    tests/test_bench_native.py 2>&1 | tee "$OUT/test_cuda.log" | tail -15
fi
if has sanitize; then
  SMOOTHFFD_SANITIZER=1 timeout 240 compute-sanitizer --tool memcheck --error-exitcode 9 \
    python3 -m pytest -q -x tests/test_cuda.py tests/test_bench_native.py -k "sanitizer_subset or upsampling" \
    > "$OUT/sanitizer.log" 2>&1
  echo "compute-sanitizer rc=$?"; grep -E "ERROR SUMMARY|passed|failed|Error" "$OUT/sanitizer.log" | head -10
fi
if has bench; then
  timeout ${BENCH_TIMEOUT:-480} python3 bench/bench_gpu.py --out "$OUT/bench.json" $BENCH_ARGS 2>&1 | tee "$OUT/bench.log" | tail -40
fi
