#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Fuzzes the readers of untrusted files and the live stereo input with libFuzzer, so
# that no file or message can crash them or make them read out of bounds: configures a clang
# build folder with -DPLANAR_GRID_BUILD_FUZZERS=ON (libraries instrumented with
# -fsanitize=fuzzer-no-link,address,undefined), builds the targets of tests/fuzz/, runs
# each for a fixed time from its seed corpus (tests/fuzz/corpus/<target>/, read only;
# new inputs go to <build>/corpus/<target>/) and fails when a target finds a crash,
# a sanitizer report, a leak, a timeout or an out-of-memory (reproducer in
# <build>/artifacts/<target>/; rerun with `<build>/tests/fuzz/<target> <file>`).
#   bash scripts/run_fuzz.sh [target ...]        (default: every target)
# FUZZ_SECONDS (default 60) per target, BUILD_DIR (default build-fuzz), JOBS (default 2),
# FUZZ_ARGS (more libFuzzer options, e.g. -runs=N).
set -euo pipefail
cd "$(dirname "$0")/.."
FUZZ_SECONDS=${FUZZ_SECONDS:-60}
BUILD_DIR=${BUILD_DIR:-build-fuzz}
JOBS=${JOBS:-2}
targets=(fuzz_map_file fuzz_map_layers fuzz_pipeline_config fuzz_calibration fuzz_pose_files
         fuzz_pcd_frame fuzz_checkpoint fuzz_live_stereo)
[ $# -gt 0 ] && targets=("$@")
command -v clang++ >/dev/null || { echo "run_fuzz: clang++ not installed" >&2; exit 1; }

configure=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DPLANAR_GRID_BUILD_FUZZERS=ON
           -DPLANAR_GRID_BUILD_TESTS=ON -DPLANAR_GRID_BUILD_VIEWER=OFF)
echo "run_fuzz: configuring $BUILD_DIR (clang, libFuzzer + ASan + UBSan)"
CC=clang CXX=clang++ cmake -S . -B "$BUILD_DIR" "${configure[@]}" >/dev/null
echo "run_fuzz: building ${targets[*]}"
cmake --build "$BUILD_DIR" -j "$JOBS" --target "${targets[@]}"

export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
summary=()
failed=0
for target in "${targets[@]}"; do
  work="$BUILD_DIR/corpus/$target"
  artifacts="$BUILD_DIR/artifacts/$target"
  log="$BUILD_DIR/$target.log"
  mkdir -p "$work" "$artifacts"
  echo "run_fuzz: $target for ${FUZZ_SECONDS} s"
  rc=0
  "$BUILD_DIR/tests/fuzz/$target" -max_total_time="$FUZZ_SECONDS" -timeout=25 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/" \
    ${FUZZ_ARGS:-} "$work" "tests/fuzz/corpus/$target" >"$log" 2>&1 || rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ "$rc" -ne 0 ]; then
    failed=1
    grep -E -A40 '^==[0-9]+==|runtime error|deadly signal|out-of-memory|timeout' "$log" \
      | head -80 >&2 || tail -40 "$log" >&2
    summary+=("$target: FAILED (exit $rc) after ${execs:-?} runs; see $log and $artifacts/")
  else
    summary+=("$target: ${execs:-?} runs in ${FUZZ_SECONDS} s, no finding")
  fi
done
echo "run_fuzz: summary"
printf '  %s\n' "${summary[@]}"
exit "$failed"
