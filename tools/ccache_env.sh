# Sourced by tools/setup_debian.sh and tools/run_tests.sh (after tools/python_env.sh): CMake
# compiles through ccache when it is installed (CMake reads CMAKE_CXX_COMPILER_LAUNCHER from the
# environment), so that the test build (build-tests/) reuses the objects of the package build
# (pip, build-python/): the same sources with the same flags. ccache hashes the compiler's name,
# and the package build takes Python's (sysconfig CXX: g++ on Debian) where CMake alone takes
# c++, so CXX is set to Python's for both. A launcher or CXX already set in the environment
# wins; AOS_CCACHE=0 turns it all off. Only these scripts set them: a plain `pip install .` or
# CMake build does not.
if [[ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" && "${AOS_CCACHE:-1}" != 0 ]] &&
    command -v ccache >/dev/null 2>&1; then
  export CMAKE_CXX_COMPILER_LAUNCHER=ccache
  if [[ -z "${CXX:-}" ]]; then
    CXX="$("${AOS_PYTHON}" -c 'import sysconfig
print((sysconfig.get_config_var("CXX") or "c++").split()[0])')"
    export CXX
  fi
fi
