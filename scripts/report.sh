#!/usr/bin/env bash
# Writes docs/results.md and its plots (docs/images/results_*.png): the paper's Tables 2-4
# (approximation errors), convergence plots and timings (Tables 1, 5, 6: CPU here, GPU from
# docs/benchmarks.md). Run on demand (a few minutes), not in CI.
#
#   bash scripts/report.sh [--quick] [--no-bench]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# Debian's python3 has numpy and matplotlib (python3-matplotlib, installed by setup.sh).
PY="${PYTHON:-/usr/bin/python3}"
[ -x "$PY" ] || PY=python3
"$PY" -c 'import smoothffd._core' 2>/dev/null || PYTHONPATH=python "$PY" -c 'import smoothffd._core' \
    || { echo "report.sh: build the core first: bash scripts/build.sh" >&2; exit 1; }
PYTHONPATH="$ROOT/python${PYTHONPATH:+:$PYTHONPATH}" "$PY" scripts/report.py "$@"
