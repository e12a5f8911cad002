#!/usr/bin/env bash
# On a machine with an NVIDIA GPU, CUDA 13 and Nsight Compute (ncu): build, the GPU tests, the
# quick benchmark (W1 L=10), then Nsight Compute on the inline kernel at L=10 (SASS-level
# counters, tarred with the details page).
#   bash bench/gpu_profile.sh
# SANITIZE=1 adds memcheck + racecheck (bench/gpu_sanitize.sh); SKIP_NCU=1 leaves the profile out; LEVELS="10 4" picks the profiled levels.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
STEPS=${STEPS:-"build test bench"} BENCH_ARGS=${BENCH_ARGS:-"--iters 100 --quick"} bash bench/gpu_run.sh 2>&1 | grep -v "^ *Function\|REG:" | tail -40
export PATH="$PATH:/usr/local/cuda/bin" PYTHONPATH="$PWD/python"
# Spills a function (local loads/stores in the SASS), for the k_inline instances.
cuobjdump --dump-sass python/smoothffd/libsmoothffd_cuda.so 2>/dev/null | awk '/Function : /{f=$3} /STL|LDL/{n[f]++} END{for (k in n) print n[k], k}' | grep k_inline | sed 's/EEEvNS_8PlanView.*//'
[ "${SANITIZE:-0}" = 1 ] && bash bench/gpu_sanitize.sh
[ "${SKIP_NCU:-0}" = 1 ] && exit 0
mkdir -p /tmp/prof && cd /tmp/prof
for L in ${LEVELS:-10}; do
  timeout 200 ncu --clock-control none --kernel-name regex:k_inline --launch-skip 3 --launch-count 1 --set full \
    --import-source yes -o prof_L$L python3 "$OLDPWD/bench/profile_gpu.py" --level $L --frames 5 > ncu_L$L.log 2>&1
  echo "ncu L=$L rc=$?"
  ncu -i prof_L$L.ncu-rep --page details > details_L$L.txt 2>&1
  ncu -i prof_L$L.ncu-rep --page source --csv --print-source sass > sass_L$L.csv 2>&1
  grep -E "Duration|Registers Per|Achieved Occupancy|Issue Slots Busy|Executed Instructions  |Waves Per SM|DRAM Through" details_L$L.txt
done
tar czf "$OUT/prof.tgz" details_L*.txt sass_L*.csv ncu_L*.log
