#!/usr/bin/env bash
# The test command (README): installs what is needed (apt, the Blenders, the Debian 13 chroot
# for Python 3.13), builds the shipped artefacts (scripts/package.sh -> dist/), then tests:
#   1. the native unit tests (CTest), the same under ASan + UBSan, a bounded fuzzing run;
#   2. every pytest suite against the cp311 WHEEL installed in a fresh venv, run from outside
#      the source tree (SMOOTHFFD_TEST_INSTALLED=1: the tests fail if the tree's copy is used)
#      with the CUDA toolkit hidden,
#      the Blender suites installing dist/'s extension / legacy zip into each Blender;
#   3. the cp313 wheel in a fresh Python 3.13 venv (the core's own suites that need no Blender).
# Arguments go to the cp311 pytest run (e.g. -k parity).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
# The development build (build/: CTest, fuzzing, demo scenes) needs no CUDA: the wheels have it.
CMAKE_ARGS="${CMAKE_ARGS:-} -DSMOOTHFFD_CUDA=OFF" bash scripts/setup.sh
bash scripts/setup_blender.sh
echo "== packaging (scripts/package.sh)"
bash scripts/package.sh
echo "== native unit tests (CTest)"
ctest --test-dir build --output-on-failure --no-tests=error   # no GTest: no tests, a failure
echo "== native unit tests under AddressSanitizer + UBSan"
bash scripts/sanitize.sh
echo "== bounded fuzzing"
bash scripts/fuzz.sh

# Fresh venvs with the wheels from dist/ and the tests' own needs, nothing from the tree.
echo "== pytest: cp311 wheel in a fresh venv"
VENV="$ROOT/build/venv-test311"
rm -rf "$VENV"
/usr/bin/python3 -m venv "$VENV"
"$VENV/bin/pip" install -q --upgrade pip
"$VENV/bin/pip" install -q numpy pytest dist/smoothffd-*-cp311-*.whl
RUN="$(mktemp -d)"
trap 'rm -rf "$RUN"' EXIT
# With the CUDA toolkit hidden (scripts/without_cuda.sh), as on users' machines.
(cd "$RUN" && SMOOTHFFD_TEST_INSTALLED=1 bash "$ROOT/scripts/without_cuda.sh" \
    "$VENV/bin/python" -m pytest -q -ra -p no:cacheprovider "$ROOT/tests" "$@")

echo "== pytest: cp313 wheel in a fresh Python 3.13 venv (Debian 13 chroot)"
bash scripts/py313.sh sh -c "rm -rf /opt/venv-test313 && python3.13 -m venv /opt/venv-test313 &&
    /opt/venv-test313/bin/pip install -q numpy pytest $ROOT/dist/smoothffd-*-cp313-*.whl"
bash scripts/py313.sh sh -c "cd $RUN && SMOOTHFFD_TEST_INSTALLED=1 /opt/venv-test313/bin/python -m pytest \
    -q -ra -p no:cacheprovider $ROOT/tests/test_deform_basics.py $ROOT/tests/test_lattices.py \
    $ROOT/tests/test_cli.py $ROOT/tests/test_sphere_and_sharp.py $ROOT/tests/test_cuda_optional.py"
