#!/usr/bin/env bash
# Same-call A/B on the device: builds the working tree and a reference tree (REF, default
# ab_ref/: e.g. `mkdir ab_ref && git archive <commit> | tar -x -C ab_ref`, carried with
# carry=[".carry", "ab_ref"]), then times W1 alternately with each (bench/ab_time.py).
#   run(command="bash bench/ab_device.sh", carry=[".carry", "ab_ref"], kind="nvidia-h100-x1")
# ROUNDS (default 4), LEVELS (default 10), STEPS as device_run.sh's for the working tree
# (default "build test"); NCU=1 adds the profile; VARIANTS: space-separated NAME=VALUE settings, each also timed with
# the working tree (label = the setting). Logs under $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
REF=${REF:-ab_ref}
export PATH="$PATH:/usr/local/cuda/bin" PYTHONUNBUFFERED=1
( cd "$REF" && BUILD_DIR=/tmp/ref-build PYTHON="$(command -v python3)" CMAKE_ARGS="-DSMOOTHFFD_TESTS=OFF" \
    bash scripts/build.sh > "$OUT/ref_build.log" 2>&1; echo "ref build rc=$?" ) &
STEPS=${STEPS:-"build test"} bash bench/device_run.sh 2>&1 | grep -v "^ *Function\|REG:\|STACK:" | tail -20
wait
for r in $(seq 1 "${ROUNDS:-4}"); do
  for L in ${LEVELS:-10}; do
    PYTHONPATH="$REF/python" python3 bench/ab_time.py --level "$L" --label ref
    PYTHONPATH="$PWD/python" python3 bench/ab_time.py --level "$L" --label new
    for v in ${VARIANTS:-}; do PYTHONPATH="$PWD/python" python3 bench/ab_time.py --level "$L" --label "$v" --env "$v"; done
  done
done 2>&1 | tee "$OUT/ab.log"
python3 - "$OUT/ab.log" <<'PY'
import json, sys, collections, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
by = collections.defaultdict(list)
for r in rows:
    by[(r["level"], r["label"])].append(r)
for (L, lab), rs in sorted(by.items()):
    print(f"L={L} {lab}: events {statistics.median(r['events'] for r in rs):.4f} "
          f"queued {statistics.median(r.get('queued', float('nan')) for r in rs):.4f} "
          f"graph {statistics.median(r['graph'] for r in rs):.4f} floor {statistics.median(r['floor'] for r in rs):.4f} (n={len(rs)})")
PY
# NCU=1: then Nsight Compute on the working tree's kernel (bench/profile_device.sh's profile).
[ "${NCU:-0}" = 1 ] && STEPS=" " BENCH_ARGS=" " bash bench/profile_device.sh 2>&1 | tail -12
exit 0
