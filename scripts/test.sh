#!/usr/bin/env bash
# The test command (README): installs what is needed (apt, the Blenders, the Debian 13 chroot
# for Python 3.13, Wine with Windows CPythons and a Debian arm64 root for qemu), builds the
# shipped artefacts (scripts/package.sh -> dist/), then tests:
#   1. the native unit tests (CTest), the same under ASan + UBSan, a bounded fuzzing run;
#   2. every pytest suite against the cp311 Linux x86-64 WHEEL installed in a fresh venv, run
#      from outside the source tree (SMOOTHFFD_TEST_INSTALLED=1: the tests fail if the tree's
#      copy is used) with the CUDA toolkit hidden: the Blender suites installing dist/'s
#      extension / legacy zip into each Blender, tests/test_platforms.py running the Windows
#      wheels under Wine and the Linux aarch64 wheel under qemu, and checking the macOS ones;
#   3. the cp313, cp312 and cp310 wheels in fresh venvs of those Pythons (the core's own suites
#      that need no Blender);
#   4. the sdist, built from source by pip in a fresh venv with CUDA hidden (a CPU-only build).
# Arguments go to the cp311 pytest run (e.g. -k parity). The cp311 run spreads its tests over
# the machine's cores (pytest-xdist, at most 4 workers: every Blender check is one process).
# Each stage's time is printed at the end.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
CACHE="${SMOOTHFFD_CACHE:-$HOME/.cache/smoothffd}"
STAGES=()
STAGE="" STAGE_AT=$SECONDS
stage() {   # stage NAME: ends the running stage (its time noted) and starts NAME
    [ -z "$STAGE" ] || STAGES+=("$(printf '%5d s  %s' $((SECONDS - STAGE_AT)) "$STAGE")")
    STAGE="$1" STAGE_AT=$SECONDS
    [ -z "$1" ] || echo "== $1"
}
report() {
    stage ""
    echo "== stage times (total $((SECONDS / 60)) min $((SECONDS % 60)) s)"
    printf '%s\n' "${STAGES[@]}"
}
RUN=""
trap 'rc=$?; [ -z "$RUN" ] || rm -rf "$RUN"; report; exit $rc' EXIT
stage "set-up: development build, Blenders, other platforms' Pythons"
# The development build (build/: CTest, fuzzing, demo scenes) needs no CUDA: the wheels have it.
CMAKE_ARGS="${CMAKE_ARGS:-} -DSMOOTHFFD_CUDA=OFF" bash scripts/setup.sh
bash scripts/setup_blender.sh
bash scripts/setup_platforms.sh
stage "packaging (scripts/package.sh)"
bash scripts/package.sh
stage "native unit tests (CTest)"
ctest --test-dir build --output-on-failure --no-tests=error   # no GTest: no tests, a failure
stage "native unit tests under AddressSanitizer + UBSan"
bash scripts/sanitize.sh
stage "bounded fuzzing"
bash scripts/fuzz.sh

# Fresh venvs with the wheels from dist/ and the tests' own needs, nothing from the tree.
stage "pytest: cp311 wheel in a fresh venv"
VENV="$ROOT/build/venv-test311"
rm -rf "$VENV"
/usr/bin/python3 -m venv "$VENV"
"$VENV/bin/pip" install -q --upgrade pip
"$VENV/bin/pip" install -q numpy pytest pytest-xdist dist/smoothffd-*-cp311-cp311-manylinux_2_28_x86_64.whl
RUN="$(mktemp -d)"
# With the CUDA toolkit hidden (scripts/without_cuda.sh), as on users' machines. Tests that
# share one resource carry an xdist_group mark (--dist loadgroup: one worker runs them).
(cd "$RUN" && SMOOTHFFD_TEST_INSTALLED=1 bash "$ROOT/scripts/without_cuda.sh" \
    "$VENV/bin/python" -m pytest -q -ra -p no:cacheprovider -n auto --maxprocesses 4 \
    --dist loadgroup --durations 15 "$ROOT/tests" "$@")

stage "pytest: cp313 wheel in a fresh Python 3.13 venv (Debian 13 chroot)"
bash scripts/py313.sh sh -c "rm -rf /opt/venv-test313 && python3.13 -m venv /opt/venv-test313 &&
    /opt/venv-test313/bin/pip install -q numpy pytest $ROOT/dist/smoothffd-*-cp313-cp313-manylinux_2_28_x86_64.whl"
CORE_SUITES="tests/test_deform_basics.py tests/test_lattices.py tests/test_cli.py tests/test_sphere_and_sharp.py tests/test_cuda_optional.py"
bash scripts/py313.sh sh -c "cd $RUN && SMOOTHFFD_TEST_INSTALLED=1 /opt/venv-test313/bin/python -m pytest \
    -q -ra -p no:cacheprovider $(for t in $CORE_SUITES; do printf '%s ' "$ROOT/$t"; done)"

# CPython 3.12 (Ubuntu 24.04's) and 3.10 (official Blender 3.4-4.0's): pyenv's interpreters.
PYENV_VERSIONS="${PYENV_ROOT:-$HOME/.pyenv}/versions"
for v in 3.12 3.10; do
    stage "pytest: cp${v/./} wheel in a fresh Python $v venv"
    py=$(ls -d "$PYENV_VERSIONS/$v".*/bin/python$v 2>/dev/null | sort -V | tail -1)
    [ -x "$py" ] || { echo "test.sh: no Python $v in $PYENV_VERSIONS (pyenv install $v)" >&2; exit 1; }
    venv="$ROOT/build/venv-test${v/./}"
    rm -rf "$venv"
    "$py" -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check numpy pytest \
        dist/smoothffd-*-cp${v/./}-cp${v/./}-manylinux_2_28_x86_64.whl
    (cd "$RUN" && SMOOTHFFD_TEST_INSTALLED=1 bash "$ROOT/scripts/without_cuda.sh" "$venv/bin/python" -m pytest \
        -q -ra -p no:cacheprovider $(for t in $CORE_SUITES; do printf '%s ' "$ROOT/$t"; done))
done

# The sdist as `pip install` meets it on a machine with a compiler and no CUDA: built from
# source (CPU only), then the core's first suite from the installed package.
stage "pytest: the sdist built from source by pip in a fresh venv (CUDA hidden)"
venv="$ROOT/build/venv-sdist"
rm -rf "$venv"
/usr/bin/python3 -m venv "$venv"
"$venv/bin/pip" install -q --disable-pip-version-check numpy pytest
bash scripts/without_cuda.sh "$venv/bin/pip" install -q --disable-pip-version-check dist/smoothffd-*.tar.gz
(cd "$RUN" && SMOOTHFFD_TEST_INSTALLED=1 "$venv/bin/python" -m pytest -q -ra -p no:cacheprovider \
    "$ROOT/tests/test_deform_basics.py" "$ROOT/tests/test_cuda_optional.py")
