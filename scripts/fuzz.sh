#!/usr/bin/env bash
# Bounded fuzzing (about two minutes in all): the libFuzzer target over plan build + CPU
# evaluation (native/fuzz/fuzz_plan.cpp, clang++ -fsanitize=fuzzer,address,undefined; the core's
# sources but the CUDA backend's), the OBJ reader (native/fuzz/fuzz_obj.py: atheris when
# build/venv-fuzz has it, else a seeded mutation loop), the lattice JSON reader
# (fuzz_lattice_json.py, the same two engines), the command line's argument handling
# (fuzz_cli.py, in process) and the bindings' argument conversion (fuzz_bindings.py, in a child
# process so that a segfault is caught).
# Seeds: native/fuzz/corpus/{plan,obj,lattice}; new inputs go to build/fuzz/corpus-*, crashes to
# build/fuzz/crash-*, each fuzzer's whole output to build/fuzz/fuzz_*.out. FUZZ_SECONDS (default
# 30) for fuzz_plan and fuzz_obj, FUZZ_PY_SECONDS (default half of it) for each of the other
# three. Exit status non-zero on any crash and whenever a fuzzer exits non-zero (one that
# fails to start, say).
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${FUZZ_SECONDS:-30}
PY_SECS=${FUZZ_PY_SECONDS:-$((SECS / 2))}
OUT=build/fuzz
mkdir -p "$OUT/obj" "$OUT/corpus-plan" "$OUT/corpus-obj"
rm -f "$OUT"/crash-*  # artifacts of this run only
CXX=${FUZZ_CXX:-clang++}
command -v "$CXX" >/dev/null || { echo "fuzz.sh: $CXX not found (apt-get install -y clang libclang-rt-14-dev)"; exit 2; }
FLAGS=(-std=c++17 -O2 -gline-tables-only -fsanitize=fuzzer-no-link,address,undefined
       -fno-sanitize-recover=all -Inative -I/usr/include/eigen3)
objs=()
# The core's sources: not those of the CUDA library (cuda/) nor _core's proxy of it (cuda_proxy/),
# compiled as many at a time as the machine has cores.
JOBS=$(nproc 2>/dev/null || echo 2)
running=0 failed=0
for src in $(ls native/smoothffd/*/*.cpp | grep -v -e "^native/smoothffd/cuda/" -e "^native/smoothffd/cuda_proxy/") \
           native/fuzz/fuzz_plan.cpp; do
  o="$OUT/obj/$(echo "${src%.cpp}" | tr / _).o"
  objs+=("$o")
  # Rebuild when the source or any core header is newer than the object.
  if [ ! -f "$o" ] || [ "$src" -nt "$o" ] || [ -n "$(find native/smoothffd -name '*.hpp' -newer "$o" | head -1)" ]; then
    echo "fuzz.sh: compiling $src"
    rm -f "$o"   # a failed compile leaves no object that looks current
    "$CXX" "${FLAGS[@]}" -c "$src" -o "$o" &
    running=$((running + 1))
    if [ "$running" -ge "$JOBS" ]; then
      wait -n || failed=1
      running=$((running - 1))
    fi
  fi
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=1
  running=$((running - 1))
done
[ "$failed" = 0 ] || { echo "fuzz.sh: compiling the fuzz build failed (above)"; exit 1; }
"$CXX" -fsanitize=fuzzer,address,undefined "${objs[@]}" -o "$OUT/fuzz_plan" -lpthread
echo "== fuzz_plan: ${SECS}s"
rc=0
UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 "$OUT/fuzz_plan" -max_total_time="$SECS" \
  -max_len=4096 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$OUT/crash-plan-" \
  "$OUT/corpus-plan" native/fuzz/corpus/plan > "$OUT/fuzz_plan.out" 2>&1 || rc=$?
grep -E "^#[0-9]+ *(DONE|INITED)|stat::|ERROR|SUMMARY|fuzz_plan:|Test unit written" "$OUT/fuzz_plan.out" || true
if ls "$OUT"/crash-plan-* >/dev/null 2>&1; then echo "fuzz_plan: CRASH (see $OUT/crash-plan-*)"; exit 1; fi
if [ "$rc" != 0 ]; then echo "fuzz_plan: exit status $rc (see $OUT/fuzz_plan.out)"; exit 1; fi
echo "== fuzz_obj: ${SECS}s"
PY=/usr/bin/python3
[ -x build/venv-fuzz/bin/python ] && PY=build/venv-fuzz/bin/python
rc=0
PYTHONPATH=python "$PY" native/fuzz/fuzz_obj.py --seconds "$SECS" --corpus native/fuzz/corpus/obj --out "$OUT" \
  > "$OUT/fuzz_obj.out" 2>&1 || rc=$?
grep -E "^fuzz_obj|^#[0-9]+ *(DONE|INITED)|stat::|Error|Traceback|^  |CRASH|Test unit written" "$OUT/fuzz_obj.out" || true
if ls "$OUT"/crash-obj-* >/dev/null 2>&1; then echo "fuzz_obj: CRASH (see $OUT/crash-obj-*)"; exit 1; fi
if [ "$rc" != 0 ]; then echo "fuzz_obj: exit status $rc (see $OUT/fuzz_obj.out)"; exit 1; fi
for target in lattice_json cli bindings; do
  echo "== fuzz_$target: ${PY_SECS}s"
  args=(--seconds "$PY_SECS" --out "$OUT")
  [ "$target" = lattice_json ] && args+=(--corpus native/fuzz/corpus/lattice)
  rc=0
  PYTHONPATH=python "$PY" native/fuzz/fuzz_$target.py "${args[@]}" > "$OUT/fuzz_$target.out" 2>&1 || rc=$?
  grep -E "^fuzz_|^#[0-9]+ *(DONE|INITED)|stat::|Error|Traceback|^  |CRASH|Test unit written" "$OUT/fuzz_$target.out" || true
  name=${target%_json}
  if ls "$OUT"/crash-"$name"-* >/dev/null 2>&1; then echo "fuzz_$target: CRASH (see $OUT/crash-$name-*)"; exit 1; fi
  if [ "$rc" != 0 ]; then echo "fuzz_$target: exit status $rc (see $OUT/fuzz_$target.out)"; exit 1; fi
done
echo "fuzz.sh: no crash"
