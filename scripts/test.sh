#!/usr/bin/env bash
# The test command (README): installs what is needed (apt, Blender, the bpy venv), builds,
# then runs the native unit tests (CTest), the same under ASan + UBSan, a bounded fuzzing run
# (about a minute) and every pytest suite, the Blender ones included.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/setup_blender.sh
echo "== native unit tests (CTest)"
ctest --test-dir build --output-on-failure
echo "== native unit tests under AddressSanitizer + UBSan"
bash scripts/sanitize.sh
echo "== bounded fuzzing"
bash scripts/fuzz.sh
echo "== pytest"
PYTHONPATH=python /usr/bin/python3 -m pytest -q -ra tests "$@"
