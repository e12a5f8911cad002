#!/usr/bin/env bash
# A/B on a machine with an NVIDIA GPU and CUDA 13: builds the working tree and one or more
# reference trees, then times W1 alternately with each in fresh processes (bench/ab_time.py),
# so that every tree is compared on the same machine in the same run (the floor moves a few
# per cent between runs).
#   mkdir ab_ref && git archive <commit> native python/smoothffd CMakeLists.txt scripts bench tests | tar -x -C ab_ref
#   bash bench/gpu_ab.sh
# REFS: the reference trees, space-separated folders in the repository (default "${REF:-ab_ref}"),
#   each built in parallel; label = the folder's name ("ref" for ab_ref). An experiment on a branch is a
#   reference tree too: `git archive exp/x ... | tar -x -C ab_exp1`.
# TEST_REFS: those of REFS to run the GPU tests in as well (their archives must hold tests/):
#   REF_TESTS (default tests/test_cuda.py tests/test_render_vertices.py), those a tree has.
# NEW=0: no working tree (build, tests, timing): compare archives only, e.g. ab_new from
#   `git archive HEAD ...` against ab_ref, when the working tree holds others' unfinished work.
#   Labels: "ref" for ab_ref, "new" for ab_new and the working tree, else the folder's name.
# ROUNDS (default 4), LEVELS (default 10), STEPS as gpu_run.sh's for the working tree
# (default "build test"); NCU=1 adds the profile; CASES: semicolon-separated sets of
# bench/ab_time.py options (e.g. "--limit 49152;--degree 4"), each timed with every tree as well
# (label = tree + case), at CASE_LEVELS (default LEVELS). ARCHS: CUDA architectures of every tree's build (default: the
# project's; 90-real builds an H100's kernels alone, in a fifth of the time). Logs under $OUT.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/sffd-out}; mkdir -p "$OUT"
REFS=${REFS:-${REF:-ab_ref}}
export PATH="$PATH:/usr/local/cuda/bin" PYTHONUNBUFFERED=1
label() { case "$1" in ab_ref) echo ref ;; ab_new) echo new ;; *) basename "$1" ;; esac; }
if [ -n "${EIGEN_COPY:-}" ]; then  # EIGEN_COPY as gpu_run.sh's, before any build starts
  cp -r "$EIGEN_COPY/eigen3" /usr/include/ && mkdir -p /usr/share/eigen3/cmake && cp "$EIGEN_COPY"/eigen3-cmake/* /usr/share/eigen3/cmake/
fi
ARCH_ARG=${ARCHS:+-DSMOOTHFFD_CUDA_ARCHITECTURES=$ARCHS}
export ARCH_ARG
for ref in $REFS; do
  ( cd "$ref" && BUILD_DIR="/tmp/build-$(basename "$ref")" PYTHON="$(command -v python3)" \
      CMAKE_ARGS="-DSMOOTHFFD_TESTS=OFF $ARCH_ARG" bash scripts/build.sh > "$OUT/build_$(basename "$ref").log" 2>&1
    echo "$ref build rc=$?" ) &
done
[ "${NEW:-1}" = 1 ] && STEPS=${STEPS:-"build test"} bash bench/gpu_run.sh 2>&1 | grep -v "^ *Function\|REG:\|STACK:" | tail -20
wait
for ref in ${TEST_REFS:-}; do
  echo "== GPU tests in $ref"
  tests=()
  for t in ${REF_TESTS:-tests/test_cuda.py tests/test_render_vertices.py}; do [ -f "$ref/$t" ] && tests+=("$t"); done
  ( cd "$ref" && PYTHONPATH="$PWD/python" timeout ${TEST_TIMEOUT:-300} python3 -m pytest -q ${PYTEST_X--x} "${tests[@]}" \
      2>&1 | tee "$OUT/test_$(basename "$ref").log" | tail -4 )
done
IFS=';' read -r -a cases <<< "${CASES:-}"
for r in $(seq 1 "${ROUNDS:-4}"); do
  for L in ${LEVELS:-10}; do
    lc=("")
    [[ " ${CASE_LEVELS:-${LEVELS:-10}} " == *" $L "* ]] && lc+=("${cases[@]}")
    for c in "${lc[@]}"; do
      # shellcheck disable=SC2086
      for ref in $REFS; do PYTHONPATH="$ref/python" python3 bench/ab_time.py --level "$L" $c --label "$(label "$ref")${c:+ $c}"; done
      # shellcheck disable=SC2086
      [ "${NEW:-1}" = 1 ] && PYTHONPATH="$PWD/python" python3 bench/ab_time.py --level "$L" $c --label "new${c:+ $c}"
    done
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
          f"graph {statistics.median(r['graph'] for r in rs):.4f} floor {statistics.median(r['floor'] for r in rs):.4f} (n={len(rs)}) "
          f"patches {rs[0].get('patches')} samples {rs[0].get('samples')} outputs {rs[0].get('outputs')}")
PY
# NCU=1: then Nsight Compute on the working tree's kernel (bench/gpu_profile.sh's profile).
[ "${NCU:-0}" = 1 ] && STEPS=" " BENCH_ARGS=" " bash bench/gpu_profile.sh 2>&1 | tail -12
exit 0
