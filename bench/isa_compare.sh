#!/usr/bin/env bash
# Same-run comparison of the CPU evaluator's builds on W1 (bench/bench_cpu.py): the shipped
# build (x86-64-v2 baseline + x86-64-v3 copy chosen at run time) against -march=native, and,
# for the record, x86-64-v4 (AVX-512) and the x86-64-v2 path alone (what a pre-AVX2 CPU runs).
# Each build goes to its own build dir (CPU only, no tests) and its module to its own package
# copy under build-bench/; the runs then alternate between the builds REPS times (the machine
# is noisy) and the table gives each build's median over the runs of bench_cpu's per-run
# median deform time.
#
#   bash bench/isa_compare.sh                 # VARIANTS="dispatch native v4 v2only" REPS=7
#   VARIANTS="dispatch native" REPS=11 LEVELS="10" bash bench/isa_compare.sh
#   BUILD_ONLY=1 bash bench/isa_compare.sh   # the builds only
set -euo pipefail
cd "$(dirname "$0")/.."
VARIANTS=${VARIANTS:-"dispatch native v4 v2only"}
REPS=${REPS:-7}
LEVELS=${LEVELS:-"4 10 16"}
BENCH_ARGS=${BENCH_ARGS:-"--repeats 7"}
PY=${PYTHON:-/usr/bin/python3}
OUT=build-bench
pyb=$("$PY" -c 'import pybind11; print(pybind11.get_cmake_dir())' 2>/dev/null || true)
for v in $VARIANTS; do
  case $v in
    dispatch) args=(-DSMOOTHFFD_ARCH=x86-64-v2 -DSMOOTHFFD_DISPATCH=ON) ;;
    native) args=(-DSMOOTHFFD_ARCH=native) ;;
    v4) args=(-DSMOOTHFFD_ARCH=x86-64-v4) ;;
    v3) args=(-DSMOOTHFFD_ARCH=x86-64-v3) ;;
    v2only) args=(-DSMOOTHFFD_ARCH=x86-64-v2 -DSMOOTHFFD_DISPATCH=OFF) ;;
    *) echo "isa_compare.sh: unknown variant $v"; exit 2 ;;
  esac
  bd=$OUT/$v
  # SKBUILD=ON: the module stays in the build dir (python/smoothffd/ is left alone).
  cmake -S . -B "$bd" -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$PY" -DSMOOTHFFD_CUDA=OFF \
    -DSMOOTHFFD_TESTS=OFF -DSKBUILD=ON ${pyb:+-Dpybind11_DIR="$pyb"} "${args[@]}" >/dev/null
  cmake --build "$bd" --target _core -j"$(nproc)" 2>&1 | grep -E "error|Error" || true
  rm -rf "$OUT/pkg-$v"
  mkdir -p "$OUT/pkg-$v"
  cp -r python/smoothffd "$OUT/pkg-$v/"
  rm -f "$OUT/pkg-$v"/smoothffd/_core*.so "$OUT/pkg-$v"/smoothffd/libsmoothffd_cuda*.so
  cp "$bd"/native/_core*.so "$OUT/pkg-$v/smoothffd/"
done
[ -n "${BUILD_ONLY:-}" ] && exit 0
echo "isa_compare: $(date -u '+%Y-%m-%d %H:%M UTC'), $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores"
"$PY" - "$OUT" "$REPS" "$LEVELS" "$BENCH_ARGS" $VARIANTS <<'EOF'
import os, re, statistics, subprocess, sys
out, reps, levels, bench_args, variants = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(), sys.argv[4].split(), sys.argv[5:]
times = {(v, L): [] for v in variants for L in levels}
isa = {}
for rep in range(reps):
    for v in (variants if rep % 2 == 0 else variants[::-1]):  # alternate the order too
        env = dict(os.environ, PYTHONPATH=os.path.abspath(f"{out}/pkg-{v}"))
        isa[v] = subprocess.run([sys.executable, "-c", "from smoothffd import _core; print(_core.cpu_isa())"],
                                env=env, capture_output=True, text=True, check=True).stdout.strip()
        r = subprocess.run([sys.executable, "bench/bench_cpu.py", "--levels", *levels, *bench_args],
                           env=env, capture_output=True, text=True, check=True)
        for line in r.stdout.splitlines():
            m = re.match(r"\s*(\d+)\s+[\d.]+\s+([\d.]+)\s", line)
            if m and m.group(1) in levels:
                times[(v, m.group(1))].append(float(m.group(2)))
    print(f"  rep {rep + 1}/{reps}: " + ", ".join(f"{v} L{L} {times[(v, L)][-1]:.1f}" for v in variants for L in levels), flush=True)
print(f"\nW1 deform ms, median of {reps} alternating runs (each run: bench_cpu.py's median of its repeats)")
print(f"{'build':>10} {'path':>10} " + " ".join(f"{'L=' + L:>27}" for L in levels))
ref = variants[0]
for v in variants:
    cells = []
    for L in levels:
        med = statistics.median(times[(v, L)])
        rel = med / statistics.median(times[(ref, L)])
        cells.append(f"{med:7.1f} ({rel:4.2f}x) min {min(times[(v, L)]):6.1f}")
    print(f"{v:>10} {isa[v]:>10} " + " ".join(f"{c:>27}" for c in cells))
print(f"(x: median relative to {ref}'s; min: the fastest run)")
EOF
