#!/usr/bin/env bash
# The first thing to run: installs what the demo uses (the build tools, numpy, matplotlib and
# Debian's Blender: `scripts/setup.sh --demo`, `scripts/setup_blender.sh --only blender-3.4`)
# and builds the Python module (idempotent), builds the demo scenes in Blender,
# renders them with Cycles on the CPU, puts the pictures side by side and exports the Smooth
# FFD results as OBJ.
#
#   bash scripts/demo.sh [--no-setup] [--quick] [--docs] [scene ...]
#
#   --no-setup  skip the set-up above (already installed and built)
#   --quick     4 samples, 240x180 (a smoke run)
#   --docs      also refresh the downscaled README pictures in docs/images/
#   scene       any of: vase cube teapot suzanne chess knotbox (default: all)
#
# Output: out/scenes/<scene>.blend (open with `blender out/scenes/vase.blend`; the add-on must
# be installed, see docs/addon.md), out/demo/<scene>.png (comparison: original / Lattice /
# Lattice + Subsurf / Smooth FFD, with a close-up row), out/demo/<scene>_smooth_ffd.obj, and
# out/demo/<scene>/ (single renders, summary.json).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

setup=1 samples=16 size=320x240 docs=() scenes=()
for a in "$@"; do
    case "$a" in
        --no-setup) setup=0 ;;
        --quick) samples=4 size=240x180 ;;
        --docs) docs=(--docs docs/images) ;;
        -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
        -*) echo "demo.sh: unknown option $a" >&2; exit 2 ;;
        *) scenes+=("$a") ;;
    esac
done
[ ${#scenes[@]} -eq 0 ] && scenes=(vase cube teapot suzanne chess knotbox)

t_start=$SECONDS
if [ "$setup" = 1 ]; then
    bash scripts/setup.sh --demo
    bash scripts/setup_blender.sh --only blender-3.4
fi
t_setup=$((SECONDS - t_start))

# Debian's python3 has numpy and matplotlib (python3-matplotlib, installed by setup.sh).
PY="${PYTHON:-/usr/bin/python3}"
[ -x "$PY" ] || PY=python3
BLENDER="${BLENDER:-blender}"
command -v "$BLENDER" >/dev/null || { echo "demo.sh: no blender (run scripts/setup_blender.sh)" >&2; exit 1; }

mkdir -p out/scenes out/demo
log=out/demo/blender.log
: > "$log"
only=$(IFS=,; echo "${scenes[*]}")

echo "== building scenes ($only) into out/scenes/"
t0=$SECONDS
"$BLENDER" -b --factory-startup --python-exit-code 1 --python blender_scenes/build_all.py \
    -- --out out/scenes --only "$only" >>"$log" 2>&1 || { tail -30 "$log"; exit 1; }
grep -E '^scene ' "$log" | sed 's/^/   /'
t_build=$((SECONDS - t0))

echo "== rendering with Cycles on the CPU ($size, $samples samples, no denoising) into out/demo/"
t0=$SECONDS
for s in "${scenes[@]}"; do
    ts=$SECONDS
    "$BLENDER" -b "out/scenes/$s.blend" --python-exit-code 1 \
        --python blender_scenes/render_demo.py -- --out out/demo --samples "$samples" \
        --size "$size" >>"$log" 2>&1 || { tail -30 "$log"; exit 1; }
    echo "   $s: $((SECONDS - ts)) s"
done
t_render=$((SECONDS - t0))

echo "== comparison images"
"$PY" blender_scenes/composite.py --out out/demo "${docs[@]}" "${scenes[@]}"

echo
echo "demo.sh: setup ${t_setup} s, scenes ${t_build} s, renders ${t_render} s, total $((SECONDS - t_start)) s"
echo "pictures: out/demo/<scene>.png   OBJ: out/demo/<scene>_smooth_ffd.obj   scenes: out/scenes/<scene>.blend"
echo "Blender's output: $log"
