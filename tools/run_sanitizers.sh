#!/usr/bin/env bash
# Two sanitizer stages; results of the last run: docs/stability.md.
#
# 1. ctest under sanitizers: builds the C++ core and its tests with AddressSanitizer (with
#    LeakSanitizer) and UndefinedBehaviorSanitizer (CMake option AOS_SANITIZE) in build-asan/ and
#    runs every ctest there. Any report fails the test that produced it: UBSan halts on the first
#    error, ASan always does, LSan fails the process at exit.
# 2. Fuzzing: builds the libFuzzer harnesses of tests/fuzz (CMake option AOS_BUILD_FUZZERS; clang
#    with ASan and UBSan, core instrumented for coverage) in build-fuzz/ with clang++, writes the
#    seed corpora, and runs each harness for a fixed time, one after the other. Per harness it
#    prints executions, executions per second, libFuzzer's final coverage (cov: edges, ft:
#    features), and the crash files it wrote. Inputs that grow coverage are kept in
#    build-fuzz/corpus/<harness>/ and reused by the next run; findings land in
#    build-fuzz/findings/<harness>/ (crash-*, leak-*, oom-*, timeout-*), logs in
#    build-fuzz/logs/<harness>.log. Reproduce one with build-fuzz/tests/fuzz/<harness>_fuzzer
#    <file> (AOS_FUZZ_VERBOSE=1 prints what each reader said). The harness contract (only
#    std::invalid_argument with a one-line UTF-8 message may escape a reader) is in
#    tests/fuzz/fuzz_util.h. Needs clang with libFuzzer and OpenMP: on Debian/Ubuntu
#    apt-get install clang libclang-rt-14-dev libomp-14-dev (AOS_INSTALL_CLANG=1 lets this
#    script run that apt-get itself, as root, when clang++ is missing).
#
#   bash tools/run_sanitizers.sh              # both stages (fuzzing skipped with a warning
#                                             #   when clang++ is missing)
#   bash tools/run_sanitizers.sh --no-fuzz    # stage 1 only (the behaviour before the fuzzers)
#   bash tools/run_sanitizers.sh --fuzz-only  # stage 2 only
#   AOS_JOBS=2 bash tools/run_sanitizers.sh --no-fuzz -R lens/   # extra args go to ctest
#   AOS_FUZZ_SECONDS=300 AOS_FUZZ_TARGETS="scene colmap_binary" bash tools/run_sanitizers.sh --fuzz-only
#
# Environment:
#   AOS_JOBS                build jobs and parallel ctests (default: all cores)
#   AOS_SANITIZER_TIMEOUT   per-test limit of stage 1, seconds (default 1500; ASan is slow)
#   AOS_FUZZ_SECONDS        fuzzing time per harness, seconds (default 60; -max_total_time)
#   AOS_FUZZ_TARGETS        harnesses to run (default: all fourteen, all_targets below)
#   AOS_FUZZ_TIMEOUT        one input slower than this, seconds, is a finding (default 30)
#   AOS_FUZZ_MEMORY_MB      libFuzzer's -rss_limit_mb and -malloc_limit_mb (default 2048): a
#                           larger allocation is an out-of-memory finding; the core's own memory
#                           budget is set to half of it (AOS_MEMORY_LIMIT_MB, fuzz_util.h)
#   AOS_INSTALL_CLANG       1: install clang with apt-get when clang++ is missing (root only)
#   AOS_FUZZ_ARGS           more libFuzzer flags for every harness, e.g. "-fork=1
#                           -ignore_timeouts=1 -ignore_ooms=1" to keep fuzzing past a known
#                           finding (libFuzzer otherwise stops a harness at its first one)
#
# Exit status: non-zero if a ctest failed or a harness wrote a crash, leak, oom or timeout file.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
jobs="${AOS_JOBS:-$(nproc)}"

run_ctest=1
run_fuzz=1
ctest_args=()
for arg in "$@"; do
  case "${arg}" in
    --no-fuzz) run_fuzz=0 ;;
    --fuzz-only) run_ctest=0 ;;
    *) ctest_args+=("${arg}") ;;
  esac
done
if [[ ${run_ctest} == 0 && ${run_fuzz} == 0 ]]; then
  echo "run_sanitizers.sh: --no-fuzz and --fuzz-only together leave nothing to run" >&2
  exit 2
fi
if [[ ${run_ctest} == 0 && ${#ctest_args[@]} -gt 0 ]]; then
  echo "run_sanitizers.sh: --fuzz-only takes no ctest arguments (got: ${ctest_args[*]})" >&2
  exit 2
fi

status=0

# --- Stage 1: ctest under ASan/UBSan ---------------------------------------------------------
if [[ ${run_ctest} == 1 ]]; then
  build=build-asan
  cmake -S . -B "${build}" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DAOS_SANITIZE=ON \
    -DAOS_BUILD_TESTS=ON >/dev/null
  cmake --build "${build}" -j "${jobs}"
  if ! ASAN_OPTIONS="detect_leaks=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    ctest --test-dir "${build}" -j "${jobs}" --output-on-failure \
      --timeout "${AOS_SANITIZER_TIMEOUT:-1500}" ${ctest_args[@]+"${ctest_args[@]}"}; then
    status=1
  fi
fi

# --- Stage 2: libFuzzer harnesses ------------------------------------------------------------
clang_packages="clang libclang-rt-14-dev libomp-14-dev"
if [[ ${run_fuzz} == 1 && ${AOS_INSTALL_CLANG:-0} == 1 ]] && ! command -v clang++ >/dev/null; then
  echo "run_sanitizers.sh: installing ${clang_packages} (AOS_INSTALL_CLANG=1)" >&2
  # shellcheck disable=SC2086  # a list of packages
  apt-get install -y ${clang_packages} >&2 || echo "run_sanitizers.sh: apt-get failed" >&2
fi
if [[ ${run_fuzz} == 1 ]]; then
  if ! command -v clang++ >/dev/null; then
    if [[ ${run_ctest} == 1 ]]; then
      echo "WARNING: fuzzing skipped: clang++ not found (apt-get install ${clang_packages}," \
        "or AOS_INSTALL_CLANG=1; --no-fuzz silences this)" >&2
      exit "${status}"
    fi
    echo "run_sanitizers.sh: --fuzz-only needs clang++ (apt-get install ${clang_packages}," \
      "or AOS_INSTALL_CLANG=1)" >&2
    exit 2
  fi
  build=build-fuzz
  seconds="${AOS_FUZZ_SECONDS:-60}"
  memory_mb="${AOS_FUZZ_MEMORY_MB:-2048}"
  all_targets="lightfield camera_file scene focal_stack colmap_text colmap_binary"
  all_targets+=" telemetry_csv positions_csv mesh_obj mesh_ply"
  all_targets+=" image_png image_tif image_exr image_jpg"
  targets="${AOS_FUZZ_TARGETS:-${all_targets}}"
  CXX=clang++ cmake -S . -B "${build}" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DAOS_BUILD_FUZZERS=ON -DAOS_BUILD_TESTS=OFF >/dev/null
  # Only the harnesses asked for (and the seed writer): a subset builds faster.
  fuzzer_binaries=(aos_fuzz_seeds)
  for target in ${targets}; do fuzzer_binaries+=("${target}_fuzzer"); done
  cmake --build "${build}" --target "${fuzzer_binaries[@]}" -j "${jobs}"
  "${build}/tests/fuzz/aos_fuzz_seeds" "${build}/corpus/seeds" scenes
  mkdir -p "${build}/logs"

  export AOS_FUZZ_MEMORY_LIMIT_MB=$((memory_mb / 2))
  export ASAN_OPTIONS="detect_leaks=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  summary=()
  for target in ${targets}; do
    binary="${build}/tests/fuzz/${target}_fuzzer"
    if [[ ! -x "${binary}" ]]; then
      echo "run_sanitizers.sh: no harness ${target} (${binary})" >&2
      exit 2
    fi
    case "${target}" in
      colmap_*) dict=tests/fuzz/colmap.dict ;;
      *_csv) dict=tests/fuzz/csv.dict ;;
      mesh_*) dict=tests/fuzz/mesh.dict ;;
      image_*) dict="" ;;
      *) dict=tests/fuzz/json.dict ;;
    esac
    corpus="${build}/corpus/${target}"
    findings="${build}/findings/${target}"
    log="${build}/logs/${target}.log"
    mkdir -p "${corpus}" "${findings}"
    marker="$(mktemp)"
    echo "=== fuzzing ${target} for ${seconds} s (log: ${log})"
    rc=0
    # shellcheck disable=SC2086  # AOS_FUZZ_ARGS is a list of flags
    "${binary}" -max_total_time="${seconds}" -rss_limit_mb="${memory_mb}" \
      -malloc_limit_mb="${memory_mb}" -timeout="${AOS_FUZZ_TIMEOUT:-30}" -print_final_stats=1 \
      -artifact_prefix="${findings}/" ${dict:+-dict="${dict}"} ${AOS_FUZZ_ARGS:-} \
      "${corpus}" "${build}/corpus/seeds/${target}" >"${log}" 2>&1 || rc=$?
    executions="$(sed -n 's/^stat::number_of_executed_units: *//p' "${log}" | tail -n 1)"
    per_second="$(sed -n 's/^stat::average_exec_per_sec: *//p' "${log}" | tail -n 1)"
    # The last status line: "#N DONE cov: C ft: F ..." (or "#N: cov: C ft: F ..." with -fork);
    # none when an input of the corpus failed before fuzzing began.
    status_line="$(grep -E '^#[0-9]+:?[[:space:]].*cov: ' "${log}" | tail -n 1 || true)"
    coverage="$(sed -E 's/.*cov: ([0-9]+) ft: ([0-9]+).*/cov: \1 ft: \2/' <<<"${status_line}")"
    if [[ -z "${executions}" && -n "${status_line}" ]]; then  # -fork prints no final stats
      executions="$(sed -E 's/^#([0-9]+).*/\1/' <<<"${status_line}")"
      per_second="$(sed -nE 's/.*exec\/s:? ([0-9]+).*/\1/p' <<<"${status_line}")"
    fi
    crashes="$(find "${findings}" -type f -newer "${marker}" \( -name 'crash-*' -o -name 'leak-*' \
      -o -name 'oom-*' -o -name 'timeout-*' \) | sort | tr '\n' ' ')"
    slow="$(find "${findings}" -type f -newer "${marker}" -name 'slow-unit-*' | wc -l)"
    rm -f "${marker}"
    line="${target}: ${executions:-?} executions, ${per_second:-?} exec/s, ${coverage:-cov: ?}, rc ${rc}"
    if [[ ${slow} != 0 ]]; then line+=", ${slow} slow-unit file(s) (inputs over 10 s)"; fi
    if [[ -n "${crashes}" || ${rc} != 0 ]]; then
      status=1
      line+=", FINDINGS: ${crashes:-none written (see the log)}"
      grep -E '==aos-fuzz== FINDING|^==[0-9]+==ERROR|SUMMARY: |runtime error:|out-of-memory|timeout' \
        "${log}" | head -n 5 | sed 's/^/    /' || true
    fi
    echo "${line}"
    summary+=("${line}")
  done
  echo
  echo "=== fuzzing summary (${seconds} s per harness, memory limit ${memory_mb} MB)"
  printf '%s\n' "${summary[@]}"
fi

exit "${status}"
