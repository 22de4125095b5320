#!/usr/bin/env bash
# Installs everything aos needs on a Debian 12 machine, as root, from the repository root:
#   1. Debian packages: compiler and build tools, OpenCV (with contrib), Embree 3, GLM,
#      OpenImageIO, COLMAP, GDAL/PROJ (geodata), the header-only/test libraries the core uses, and
#      Chromium with its WebDriver (the browser tests of `aos-render view`), and ExifTool (FLIR
#      radiometric frames).
#   2. The Python package with its `aos-render` executable (pip install '.[test]'), into the
#      python3 on PATH, or into a virtual environment at /opt/aos-venv when that python3 is
#      Debian's externally managed one (then aos-render is linked into /usr/local/bin).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

packages=(
  cmake ninja-build g++ pkg-config ccache
  libopencv-dev libopencv-contrib-dev libembree-dev libglm-dev
  libopenimageio-dev openimageio-tools colmap libsqlite3-dev
  nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev zlib1g-dev libpng-dev libproj-dev
  proj-data libgdal-dev gdal-bin chromium chromium-driver libimage-exiftool-perl
)
# Debian's own Python (missing, or externally managed) needs its headers and venv support.
if ! command -v python3 >/dev/null 2>&1 || python3 -c 'import os, sys, sysconfig
sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_path("stdlib"), "EXTERNALLY-MANAGED"))
         and sys.prefix == sys.base_prefix else 1)'; then
  packages+=(python3 python3-dev python3-pip python3-venv)
fi
export DEBIAN_FRONTEND=noninteractive
echo "setup: installing Debian packages (${#packages[@]})"
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null

source tools/python_env.sh   # sets AOS_PYTHON (creates /opt/aos-venv if needed)
source tools/ccache_env.sh   # compile through ccache: run_tests.sh's build reuses these objects
echo "setup: building and installing the aos Python package and aos-render with ${AOS_PYTHON}"
"${AOS_PYTHON}" -m pip install -q --upgrade pip >/dev/null 2>&1 || true
"${AOS_PYTHON}" -m pip install -q '.[test]'
# Make the freshly installed executable reachable: pyenv needs a rehash for a new command (pip
# run as `python3 -m pip` does not trigger it); otherwise link it from the interpreter's scripts.
if command -v pyenv >/dev/null 2>&1; then pyenv rehash || true; fi
scripts="$("${AOS_PYTHON}" -c 'import sysconfig; print(sysconfig.get_path("scripts"))')"
if [[ "${AOS_PYTHON}" == /opt/aos-venv/* ]] || ! command -v aos-render >/dev/null 2>&1; then
  ln -sf "${scripts}/aos-render" /usr/local/bin/aos-render
fi
hash -r
echo "setup: done ($(aos-render --version))"
