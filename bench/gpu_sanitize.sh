#!/usr/bin/env bash
# compute-sanitizer memcheck and racecheck on the GPU tests' sanitizer subset (both paths,
# every inline mode); needs a build on the GPU machine first (`STEPS=build bash bench/gpu_run.sh`).
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
export PATH="$PATH:/usr/local/cuda/bin" PYTHONPATH="$PWD/python"
for tool in memcheck racecheck; do
  SMOOTHFFD_SANITIZER=1 timeout 120 compute-sanitizer --tool $tool --error-exitcode 9 \
    python3 -m pytest -q -x tests/test_cuda.py -k "sanitizer_subset" > "$OUT/$tool.log" 2>&1
  echo "compute-sanitizer $tool rc=$?"; grep -E "ERROR SUMMARY|RACECHECK SUMMARY|passed|failed|hazard" "$OUT/$tool.log" | head -5
done
