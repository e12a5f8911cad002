#!/usr/bin/env bash
# Builds an installable zip of the Blender add-on with the core bundled:
#   build/smooth_ffd-<version>.zip
#     smooth_ffd/                     (add-on package, bl_info for 3.4+,
#       blender_manifest.toml          and extension manifest for 4.2+)
#       _vendor/smoothffd/            (the core package with its compiled _core module)
# Install: Preferences > Add-ons > Install (3.4-4.1) or "Install from Disk" (4.2+).
# The compiled module must match Blender's Python (3.11 for 3.4-5.0): build it first with
# scripts/build.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT_DIR="${1:-$ROOT/build}"
VERSION="$(sed -n 's/^version = "\(.*\)"/\1/p' "$ROOT/addon/smooth_ffd/blender_manifest.toml")"
CORE="$ROOT/python/smoothffd"

shopt -s nullglob
so=("$CORE"/_core*.so)
if [ ${#so[@]} -eq 0 ]; then
    echo "build_addon_zip: no compiled core in $CORE (run scripts/build.sh first)" >&2
    exit 1
fi

STAGE="$(mktemp -d)"
trap 'rm -rf "$STAGE"' EXIT
mkdir -p "$STAGE/smooth_ffd/_vendor"
# Sources only: no caches, no editor files.
(cd "$ROOT/addon" && find smooth_ffd -name '__pycache__' -prune -o -type f \
    \( -name '*.py' -o -name '*.toml' \) -print | while read -r f; do
        mkdir -p "$STAGE/$(dirname "$f")"; cp "$f" "$STAGE/$f"; done)
(cd "$ROOT/python" && find smoothffd -name '__pycache__' -prune -o -type f \
    \( -name '*.py' -o -name '*.so' \) -print | while read -r f; do
        mkdir -p "$STAGE/smooth_ffd/_vendor/$(dirname "$f")"; cp "$f" "$STAGE/smooth_ffd/_vendor/$f"; done)

mkdir -p "$OUT_DIR"
ZIP="$OUT_DIR/smooth_ffd-$VERSION.zip"
rm -f "$ZIP"
# Python's zipfile: `zip` may not be installed; deterministic order for reproducible zips.
python3 - "$STAGE" "$ZIP" <<'PY'
import os, sys, zipfile
stage, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
    for base, dirs, files in os.walk(stage):
        dirs.sort()
        for name in sorted(files):
            path = os.path.join(base, name)
            z.write(path, os.path.relpath(path, stage))
PY
echo "build_addon_zip: $ZIP"
