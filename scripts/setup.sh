#!/usr/bin/env bash
# Installs what the build and the tests need on Debian 12 (idempotent), then builds.
# Usage: scripts/setup.sh            (apt packages + build)
set -euo pipefail
cd "$(dirname "$0")/.."

# python3-venv: scripts/package.sh and the tests' fresh venvs; qemu-user: the wheels run under
# emulated older CPUs (tests/test_isa.py); binutils: readelf/objdump for the artefact checks.
need=(cmake g++ make binutils pybind11-dev libeigen3-dev python3-dev python3-venv python3-numpy
      python3-pytest python3-matplotlib libgtest-dev clang libclang-rt-14-dev qemu-user)
missing=()
for p in "${need[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
bash scripts/build.sh
