#!/usr/bin/env bash
# Runs a command with the CUDA toolkit hidden, as on nearly every user's machine: an empty tmpfs
# over each /usr/local/cuda-* folder (so /usr/local/cuda, a link to one, is empty too) in a
# private mount namespace that ends with the command. Used by scripts/test.sh for the pytest
# runs (the packages must import and work without any CUDA library). Needs root (or sudo) and
# unshare; without them it says so and runs the command as it is.
set -euo pipefail
if [ $# -eq 0 ]; then echo "usage: without_cuda.sh COMMAND [ARGS...]" >&2; exit 2; fi
shopt -s nullglob
dirs=(/usr/local/cuda-*/)
if [ ${#dirs[@]} -eq 0 ]; then exec "$@"; fi
if [ "$(id -u)" -ne 0 ] || ! unshare --mount --propagation private true 2>/dev/null; then
    echo "without_cuda.sh: cannot make a private mount namespace here; the CUDA toolkit stays visible" >&2
    exec "$@"
fi
exec unshare --mount --propagation private bash -c '
    for d in /usr/local/cuda-*/; do mount -t tmpfs -o ro,size=1m smoothffd-no-cuda "$d"; done
    if ls /usr/local/cuda*/lib64/libcudart* >/dev/null 2>&1; then echo "without_cuda.sh: CUDA still visible" >&2; exit 1; fi
    echo "without_cuda.sh: CUDA toolkit hidden ($(ls -d /usr/local/cuda-*/ | tr "\n" " "))" >&2
    exec "$@"' bash "$@"
