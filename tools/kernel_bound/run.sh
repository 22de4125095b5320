#!/bin/bash
# What bounds the 8-bit integral kernel on this host (docs/benchmarks.md, "2026-11-28: a
# different host"): builds the F0 driver against copies of the test build's libaos_core.a in
# which the AVX2 kernel object is compiled with one variant of variants.patch (K4 = 0 is the
# kernel as shipped), then times them alternated, round by round. A measuring tool, not a test;
# nothing in the repository changes.
#   bash tools/kernel_bound/run.sh [ROUNDS] [THREADS]    (after bash tools/run_tests.sh built build-tests)
# Environment: AOS_BUILD (default build-tests), AOS_F0 (default ../shared/data/jku-f0),
# AOS_VARIANTS (default "0 1 2 3 4 5 7 8 6").
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${AOS_BUILD:-$root/build-tests}
f0=${AOS_F0:-$root/../shared/data/jku-f0}/poses/poses.json
rounds=${1:-2}
threads=${2:-1}
variants=${AOS_VARIANTS:-0 1 2 3 4 5 7 8 6}
[[ -f $build/cpp/libaos_core.a ]] || { echo "kernel_bound: no $build/cpp/libaos_core.a (run tools/run_tests.sh or set AOS_BUILD)" >&2; exit 2; }
[[ -f $f0 ]] || { echo "kernel_bound: no F0 at $f0 (set AOS_F0)" >&2; exit 2; }
declare -A name=(
  [0]="the kernel"
  [1]="taps from rows 0-2 of the frame (always in L1)"
  [2]="no accumulator traffic (sums in a register)"
  [3]="no frame reads (taps made from the shuffle control)"
  [4]="no frame reads, no accumulator traffic"
  [5]="no division (W instead of 1/W: positions clamp to the edge, reads hit the cache)"
  [7]="no division, no frame reads, no accumulator traffic"
  [8]="an empty kernel (the rest of the render)"
  [6]="two groups a step (the same bits)")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
patch -s -o "$work/kernel.cpp" "$root/cpp/aos/render/integral_kernels_avx2.cpp" "$root/tools/kernel_bound/variants.patch"
# The libraries aos-render links, as the build recorded them.
libs=$(awk '/^build cpp\/aos-render:/{f=1} f&&/LINK_LIBRARIES/{sub(/.*LINK_LIBRARIES = /,""); print; exit}' "$build/build.ninja" | sed 's#cpp/libaos_core.a##')
flags=(-I"$root/cpp" -I"$build/cpp/generated" -isystem /usr/include/opencv4 -isystem /usr/include/Imath
       -isystem /usr/include/gdal -O3 -DNDEBUG -std=c++17 -fPIC -fopenmp -DJSON_DIAGNOSTICS=1)
for v in $variants; do
  c++ "${flags[@]}" -DK4="$v" -c "$work/kernel.cpp" -o "$work/integral_kernels_avx2.cpp.o"
  cp "$build/cpp/libaos_core.a" "$work/lib$v.a"
  ar r "$work/lib$v.a" "$work/integral_kernels_avx2.cpp.o" 2>/dev/null  # replaces the member
  # shellcheck disable=SC2086
  c++ -O2 -std=c++17 -fopenmp -I"$root/cpp" "$root/tools/kernel_bound/driver.cpp" "$work/lib$v.a" $libs -o "$work/driver$v"
done
echo "F0, z = 0, 512 x 512, $threads thread(s), $rounds round(s) of 10 renders per variant; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2), family $(grep -m1 'cpu family' /proc/cpuinfo | cut -d: -f2 | tr -d ' ')"
for r in $(seq "$rounds"); do
  for v in $variants; do
    printf '%-85s ' "K4=$v ${name[$v]}:"
    "$work/driver$v" "$f0" 0 "$threads" 10
  done
done
