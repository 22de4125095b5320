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
  [6]="two groups a step (unrolled; the same bits)")
for v in $variants; do
  [[ -n ${name[$v]+x} ]] || { echo "kernel_bound: unknown variant K4=$v (known: ${!name[*]})" >&2; exit 2; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# --fuzz=0: a patch that no longer fits the kernel exactly fails instead of landing elsewhere.
patch -s --fuzz=0 -o "$work/kernel.cpp" "$root/cpp/aos/render/integral_kernels_avx2.cpp" \
  "$root/tools/kernel_bound/variants.patch"
# The kernel object's compile flags and the libraries aos-render links, as the build recorded
# them, so that K4=0 is the kernel as shipped.
rule() {  # rule BUILD-LINE-PREFIX VARIABLE: a variable of one ninja build statement
  awk -v head="$1" -v key="  $2 = " 'index($0, head) == 1 {f = 1; next}
    f && index($0, key) == 1 {print substr($0, length(key) + 1); exit}
    f && !/^  / {exit}' "$build/build.ninja"
}
object="build cpp/CMakeFiles/aos_core.dir/aos/render/integral_kernels_avx2.cpp.o:"
compile="$(rule "$object" DEFINES) $(rule "$object" INCLUDES) $(rule "$object" FLAGS)"
libs=$(rule "build cpp/aos-render:" LINK_LIBRARIES | sed 's#cpp/libaos_core.a##')
[[ $(rule "$object" FLAGS) == *-O* && -n $libs ]] || {
  echo "kernel_bound: $build/build.ninja does not read as the Ninja build of tools/run_tests.sh" >&2; exit 2; }
cd "$build"  # where the build's relative paths start
for v in $variants; do
  # shellcheck disable=SC2086
  c++ $compile -DK4="$v" -c "$work/kernel.cpp" -o "$work/integral_kernels_avx2.cpp.o"
  cp "$build/cpp/libaos_core.a" "$work/lib$v.a"
  ar r "$work/lib$v.a" "$work/integral_kernels_avx2.cpp.o"  # replaces the member of that name
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
