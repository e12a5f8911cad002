#!/usr/bin/env bash
# The closing check of a change to the CUDA kernels, on a machine with an NVIDIA GPU and CUDA 13:
# build, GPU tests, the full benchmark, the whole non-Blender suite, memcheck and racecheck on
# the sanitizer subset.
#   bash bench/gpu_final.sh
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
export PATH="$PATH:/usr/local/cuda/bin" PYTHONPATH="$PWD/python" PYTHONUNBUFFERED=1
STEPS="build test bench" BENCH_ARGS="--iters 100" BENCH_TIMEOUT=300 bash bench/gpu_run.sh 2>&1 | grep -v "^ *Function\|REG:" | tail -45
timeout 150 python3 -m pytest -q tests --ignore=tests/test_blender.py --ignore=tests/blender > "$OUT/suite.log" 2>&1
echo "whole suite rc=$?"; tail -3 "$OUT/suite.log"
bash bench/gpu_sanitize.sh
