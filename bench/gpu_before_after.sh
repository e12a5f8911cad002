#!/usr/bin/env bash
# A change's GPU check, before and after, on one machine with an NVIDIA GPU and CUDA 13: the
# GPU tests and the full benchmark on two source trees in one run (the floor moves a few per
# cent between runs, so compare only within one).
#   rm -rf ab_ref ab_new && mkdir ab_ref ab_new
#   git archive <before> native python/smoothffd CMakeLists.txt scripts bench tests | tar -x -C ab_ref
#   git archive HEAD     native python/smoothffd CMakeLists.txt scripts bench tests | tar -x -C ab_new
#   PART=tests bash bench/gpu_before_after.sh
#   PART=bench bash bench/gpu_before_after.sh
# PART=gpu: the GPU tests in both trees and memcheck in ab_new (fits a 10-minute call on a
#   fresh machine). PART=tests: the GPU tests in both trees, the whole non-Blender suite and compute-sanitizer's
#   memcheck in ab_new, and bench/bench_deliver.py (the frame into numpy) in ab_new.
# PART=bench: bench/bench_gpu.py (every case: W1 at L = 4..16, the 1M mesh, Table 5, the CPU)
#   in both trees, one after the other. ARCHS (default 90-real: the H100's kernels alone).
# Logs and JSON under $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
export PATH="$PATH:/usr/local/cuda/bin" PYTHONUNBUFFERED=1
if [ -n "${EIGEN_COPY:-}" ]; then  # Eigen copied in, on a machine without libeigen3-dev
  cp -r "$EIGEN_COPY/eigen3" /usr/include/ && mkdir -p /usr/share/eigen3/cmake && cp "$EIGEN_COPY"/eigen3-cmake/* /usr/share/eigen3/cmake/
fi
{ date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; } | tee "$OUT/env.txt"
for tree in ab_ref ab_new; do
  ( cd "$tree" && BUILD_DIR="/tmp/build-$tree" PYTHON="$(command -v python3)" \
      CMAKE_ARGS="-DSMOOTHFFD_TESTS=OFF -DSMOOTHFFD_CUDA_ARCHITECTURES=${ARCHS:-90-real}" \
      bash scripts/build.sh > "$OUT/build_$tree.log" 2>&1; echo "$tree build rc=$?" ) &
done
wait
gpu_tests="tests/test_cuda.py tests/test_render_vertices.py tests/test_compact.py tests/test_bench_native.py tests/test_lattice_weights.py"
if [ "${PART:-tests}" = tests ] || [ "${PART:-tests}" = gpu ]; then
  for tree in ab_ref ab_new; do
    have=$(cd "$tree" && for f in $gpu_tests; do [ -f "$f" ] && echo "$f"; done)
    echo "== GPU tests, $tree"
    ( cd "$tree" && PYTHONPATH="$PWD/python" timeout 200 python3 -m pytest -q $have 2>&1 | tail -4 ) \
      | tee "$OUT/gpu_tests_$tree.log"
  done
  echo "== memcheck, ab_new"
  ( cd ab_new && PYTHONPATH="$PWD/python" SMOOTHFFD_SANITIZER=1 timeout 120 compute-sanitizer --tool memcheck \
      --error-exitcode 9 python3 -m pytest -q tests/test_cuda.py -k sanitizer_subset 2>&1 | tail -3 ) \
      | tee "$OUT/memcheck_ab_new.log"
fi
if [ "${PART:-tests}" = tests ]; then
  echo "== whole non-Blender suite, ab_new"
  ( cd ab_new && PYTHONPATH="$PWD/python" timeout 220 python3 -m pytest -q tests \
      --ignore=tests/test_blender.py --ignore=tests/blender 2>&1 | tail -12 ) | tee "$OUT/suite_ab_new.log"
  echo "== bench_deliver, ab_new"
  ( cd ab_new && PYTHONPATH="$PWD/python" timeout 120 python3 bench/bench_deliver.py --levels 4 10 16 --repeats 11 ) \
      | tee "$OUT/deliver_ab_new.txt"
fi
if [ "${PART:-tests}" = bench ]; then
  for tree in ab_ref ab_new; do
    echo "== bench_gpu.py, $tree"
    ( cd "$tree" && PYTHONPATH="$PWD/python" timeout 260 python3 bench/bench_gpu.py --iters ${ITERS:-100} \
        --out "$OUT/bench_$tree.json" 2>&1 | tail -25 ) | tee "$OUT/bench_$tree.log"
  done
fi
