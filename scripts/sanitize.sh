#!/usr/bin/env bash
# Builds the native unit tests with AddressSanitizer + UndefinedBehaviorSanitizer
# (-DSMOOTHFFD_SANITIZE=ON) in build-asan/ and runs them under CTest. Any ASan report or UB
# (no recovery: -fno-sanitize-recover) fails the run. Only the test binary is built (the
# Python module is not: an ASan'd extension needs the runtime preloaded into python).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build-asan}
JOBS=${JOBS:-$(nproc)}
# clang builds this about twice as fast as g++ (Eigen's LU at -O3 with ASan is slow to compile);
# -O1 -gline-tables-only keeps the build short and the stack traces readable.
cxx=()
if command -v clang++ >/dev/null 2>&1; then cxx=(-DCMAKE_CXX_COMPILER=clang++); fi
cmake -S . -B "$BUILD_DIR" "${cxx[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSMOOTHFFD_SANITIZE=ON \
  -DSMOOTHFFD_CUDA=OFF -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
  -DCMAKE_CXX_FLAGS="-fno-sanitize-recover=all" >/dev/null
cmake --build "$BUILD_DIR" --target smoothffd_tests -j"$JOBS"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
ctest --test-dir "$BUILD_DIR" --output-on-failure --no-tests=error -j"$JOBS"
