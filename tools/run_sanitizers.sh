#!/usr/bin/env bash
# Builds the C++ core and its tests with AddressSanitizer (with LeakSanitizer) and
# UndefinedBehaviorSanitizer (CMake option AOS_SANITIZE) in build-asan/ and runs every ctest
# there. Any report fails the test that produced it: UBSan halts on the first error, ASan always
# does, LSan fails the process at exit. Results of the last run: docs/stability.md.
#
#   bash tools/run_sanitizers.sh            # configure, build (all cores), run ctest
#   AOS_JOBS=2 bash tools/run_sanitizers.sh -R lens/   # fewer jobs; extra args go to ctest
#
# AOS_SANITIZER_TIMEOUT (seconds, default 1500) is the per-test limit for this run only: under
# ASan the tests run several times slower than in the Release build.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
jobs="${AOS_JOBS:-$(nproc)}"
build=build-asan
cmake -S . -B "${build}" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DAOS_SANITIZE=ON \
  -DAOS_BUILD_TESTS=ON >/dev/null
cmake --build "${build}" -j "${jobs}"
export ASAN_OPTIONS="detect_leaks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
ctest --test-dir "${build}" -j "${jobs}" --output-on-failure \
  --timeout "${AOS_SANITIZER_TIMEOUT:-1500}" "$@"
