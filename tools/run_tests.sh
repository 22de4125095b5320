#!/usr/bin/env bash
# Runs every test: the C++ tests (ctest, from a fresh CMake build in build-tests/) and the
# Python tests (pytest, against the installed aos package). Run tools/setup_debian.sh first.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source tools/python_env.sh
source tools/ccache_env.sh   # the library's objects come from the package build (setup_debian.sh)
jobs="$(nproc)"
cmake -S . -B build-tests -G Ninja -DCMAKE_BUILD_TYPE=Release -DAOS_BUILD_TESTS=ON >/dev/null
cmake --build build-tests -j "${jobs}"
ctest --test-dir build-tests --output-on-failure -j "${jobs}"
"${AOS_PYTHON}" -m pytest tests/python -q -rs
