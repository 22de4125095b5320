# Sourced by tools/setup_debian.sh and tools/run_tests.sh: CMake compiles through ccache when it
# is installed (CMake reads CMAKE_CXX_COMPILER_LAUNCHER from the environment), so that the test
# build (build-tests/) reuses the objects of the package build (pip, build-python/): the same
# sources with the same flags. A launcher already set in the environment wins; AOS_CCACHE=0
# turns it off. Only these scripts set it: a plain `pip install .` or CMake build does not.
if [[ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" && "${AOS_CCACHE:-1}" != 0 ]] &&
    command -v ccache >/dev/null 2>&1; then
  export CMAKE_CXX_COMPILER_LAUNCHER=ccache
fi
