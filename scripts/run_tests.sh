#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs the dependencies, builds PlanarGrid and runs every test (what CI runs). Two
# builds, each compiled once:
#   build/       Release, the libraries, tools, ROS node and Python module that users run
#                (no C++ tests): a short real pipeline run with snapshots, the Python
#                tests, the ROS node's test, the installed package with the examples
#                built against it, the package installed on a clean Debian
#                (debootstrap) and used there, the API docs.
#   build-asan/  AddressSanitizer + UndefinedBehaviorSanitizer (libraries and tools -O1,
#                test sources -O0; line tables; shared libraries): every GoogleTest
#                suite and tool test under the sanitizers (the tool tests run the
#                sanitized pipeline tool on real Karlsruhe frames, and any report ends
#                a process with a failure: UBSan halts on error); any sanitizer report
#                or compiler warning fails. The ROS node (glue
#                between roscpp and Mapper, whose code the suites cover) is not built here.
# Both builds compile the libraries, tools, Python module and tests in unity batches
# (CMAKE_UNITY_BUILD: eight sources per translation unit, each header and template
# instantiation compiled once per batch instead of once per file).
# Each phase prints its wall time, and a table of all of them ends the run.
#   bash scripts/run_tests.sh
# BUILD_DIR (default build), ASAN_BUILD_DIR (default build-asan), JOBS (default 2);
# extra CMake options for both builds in CMAKE_ARGS. The data come from
# PLANAR_GRID_DATA_DIR (default ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
ASAN_BUILD_DIR=${ASAN_BUILD_DIR:-build-asan}
JOBS=${JOBS:-2}
# shellcheck source=scripts/common.sh
source scripts/common.sh

# Builds a configured folder; a compiler warning fails the build (the build is kept
# warning-free, and a warning in one configuration only is still a warning).
build_warning_free() {
  local dir=$1
  local log="$dir/build.log"
  cmake --build "$dir" -j "$JOBS" 2>&1 | tee "$log"
  if grep -qE ':[0-9]+(:[0-9]+)?: warning:' "$log"; then
    echo "run_tests: the build of $dir has warnings:" >&2
    grep -A3 -E ':[0-9]+(:[0-9]+)?: warning:' "$log" >&2
    return 1
  fi
}

release_build() {
  # shellcheck disable=SC2086
  configure_build "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DPLANAR_GRID_BUILD_TESTS=OFF -DCMAKE_UNITY_BUILD=ON \
    -DPLANAR_GRID_BUILD_PYTHON_TESTS=ON -DPLANAR_GRID_BUILD_ROS_TESTS=ON ${CMAKE_ARGS:-}
  build_warning_free "$BUILD_DIR"
}

# The main job, as the Release tool runs it, with its snapshots; the map figures the
# docs quote are checked against it (scripts/check_main_job_figures.py). Then the tests
# registered in this build: the Python tests and the ROS node's (a rosmaster, the node
# and rosbag play, label ros).
release_checks() {
  local out
  out=$(mktemp -d "${TMPDIR:-/tmp}/planar_grid_main_job.XXXXXX")
  "$BUILD_DIR/tools/planar_grid_pipeline" --config config/karlsruhe.yaml \
    --output "$out" >"$out.log" 2>&1 || { cat "$out.log" >&2; rm -rf "$out" "$out.log"; return 1; }
  local f
  for f in map.pgmap map.bt report.json trajectory.txt snapshot.png cuboids.png; do
    [ -s "$out/$f" ] || { cat "$out.log" >&2; echo "run_tests: the main job wrote no $f" >&2; return 1; }
  done
  echo "run_tests: the main job, 112 frames: $(find "$out" -maxdepth 1 -type f | wc -l) files"
  python3 scripts/check_main_job_figures.py "$out" || { rm -rf "$out" "$out.log"; return 1; }
  rm -rf "$out" "$out.log"
  ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS" --timeout 600
}

sanitizer_build() {
  # -O1 with line tables only: the reports name file and line, at a fraction of the
  # compile and link time of -O2 -g; the tests' own sources at -O0, the code under test
  # at -O1; shared libraries keep the test links small.
  # shellcheck disable=SC2086
  configure_build "$ASAN_BUILD_DIR" -DPLANAR_GRID_SANITIZE=ON -DCMAKE_UNITY_BUILD=ON \
    -DPLANAR_GRID_BUILD_TESTS=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
    "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DBUILD_SHARED_LIBS=ON \
    -DPLANAR_GRID_TEST_COMPILE_OPTIONS=-O0 -DPLANAR_GRID_BUILD_ROS_NODE=OFF \
    -DPLANAR_GRID_BUILD_ROS_TESTS=OFF ${CMAKE_ARGS:-}
  build_warning_free "$ASAN_BUILD_DIR"
}

# ctest under the sanitizers. LeakSanitizer's tracer thread, which stops the process at
# exit to scan it for leaks, can crash itself ("Tracer caught signal 11", "LeakSanitizer
# has encountered a fatal error") after the test's own cases have all passed: GCC 12's
# LSan reads a corrupt entry of a thread's dynamic-TLS vector once enough libraries with
# thread-local storage are loaded (LSAN_OPTIONS verbosity=1 shows "DTLS 24 at 0x5434-..."
# just before the crash, in the PCD input suite on some hosts). When that is in the
# output, the failed tests run once more without the thread-local-storage scan
# (use_tls=0). That scan only adds roots, so the second run can report more leaks, never
# fewer; the blocks Debian's libraries keep only in thread-local storage are suppressed
# for it (scripts/lsan_tls.supp), and its result stands. Any other failure fails.
sanitized_ctest() {
  local log
  log=$(mktemp "${TMPDIR:-/tmp}/planar_grid_ctest.XXXXXX")
  if ctest --test-dir "$ASAN_BUILD_DIR" --output-on-failure -j "$JOBS" --timeout 1500 "$@" \
    2>&1 | tee "$log"; then
    rm -f "$log"
    return 0
  fi
  if grep -q "LeakSanitizer has encountered a fatal error" "$log"; then
    # The failed tests by name, from ctest's closing list ("  148 - Name (Failed)"):
    # --rerun-failed goes by test number, which a run filtered with -E numbers otherwise.
    local failed others
    failed=$(sed -n 's/^[[:space:]]*[0-9]* - \(.*\) (Failed)$/\1/p' "$log" | paste -sd '|')
    others=$(sed -n '/The following tests FAILED:/,$p' "$log" \
      | grep -E '^[[:space:]]*[0-9]+ - ' | grep -vc ' (Failed)$' || true)
    rm -f "$log"
    if [ -z "$failed" ] || [ "$others" != 0 ]; then
      echo "run_tests: a test failed otherwise than by LeakSanitizer's tracer" >&2
      return 1
    fi
    echo "run_tests: LeakSanitizer's tracer crashed at a process exit; the failed tests ($failed)" \
      "once more, without scanning thread-local storage"
    local supp status=0
    supp=$(mktemp "${TMPDIR:-/tmp}/planar_grid_lsan.XXXXXX")
    cat scripts/lsan.supp scripts/lsan_tls.supp > "$supp"
    LSAN_OPTIONS="suppressions=$supp:use_tls=0" \
      ctest --test-dir "$ASAN_BUILD_DIR" --output-on-failure --timeout 1500 -R "^(${failed})\$" \
      || status=$?
    rm -f "$supp"
    return "$status"
  fi
  rm -f "$log"
  return 1
}

sanitizer_tests() {
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$(pwd)/scripts/lsan.supp}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
  echo "run_tests: ASAN_OPTIONS=$ASAN_OPTIONS UBSAN_OPTIONS=$UBSAN_OPTIONS"
  # The render tests (the scene renderer, the synthetic stereo scene's rendering fixture,
  # the line charts, the viewer's snapshots of meshes and octrees) open an X/GL window
  # under xvfb: Mesa's and Qt's modules are unloaded at exit, so their one-time allocations
  # leak with stacks LSan cannot name (no PlanarGrid frame in any of them). ASan and UBSan
  # stay on for them; leak detection does not.
  local render_tests='^(SceneRenderer|SyntheticStereoSceneTest|LineChart|ViewerTool\.SnapshotOf)'
  ASAN_OPTIONS=detect_leaks=0 ctest --test-dir "$ASAN_BUILD_DIR" --output-on-failure \
    -j "$JOBS" --timeout 1500 -R "$render_tests"
  # Each GoogleTest suite is one CTest test (tests/discover_suites.cmake).
  local suites cases
  suites=$(cat "$ASAN_BUILD_DIR"/tests/*/*_suites.cmake | grep -c '^add_test')
  cases=$(cat "$ASAN_BUILD_DIR"/tests/*/*_suites.cmake | awk '/^# gtest_cases/ { n += $3 } END { print n }')
  echo "run_tests: $cases GoogleTest cases in $suites suites, and the tools' tests"
  # Last, so that its summary closes the run: every other test, with leak detection.
  sanitized_ctest -E "$render_tests"
}

# The Debian package installed on a clean Debian made by debootstrap and used there
# (scripts/check_clean_system.sh): as root on CI (CI=true) or when
# PLANAR_GRID_CLEAN_SYSTEM=1 asks for it.
clean_system_check() {
  if [ "$(id -u)" = 0 ] && { [ "${CI:-}" = true ] || [ "${PLANAR_GRID_CLEAN_SYSTEM:-0}" = 1 ]; }; then
    bash scripts/check_clean_system.sh "$BUILD_DIR"
  else
    echo "run_tests: the package was not checked on a clean system (root, with CI=true or PLANAR_GRID_CLEAN_SYSTEM=1)"
  fi
}

phase deps bash scripts/install_deps.sh
phase format bash scripts/check_format.sh
phase build release_build
phase release-checks release_checks
phase install-check bash scripts/check_install.sh "$BUILD_DIR"
phase clean-system clean_system_check
phase docs bash scripts/build_docs.sh "$BUILD_DIR/docs"
phase sanitizer-build sanitizer_build
phase sanitizer-tests sanitizer_tests
