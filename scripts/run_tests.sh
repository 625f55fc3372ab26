#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs the dependencies, builds PlanarGrid and runs the whole test suite.
#   bash scripts/run_tests.sh            (build folder: build/, override with BUILD_DIR=...)
# Extra CMake options can be passed through CMAKE_ARGS, e.g. CMAKE_ARGS=-DPLANAR_GRID_SANITIZE=ON.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
bash scripts/install_deps.sh
bash scripts/check_format.sh
# shellcheck disable=SC2086
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DPLANAR_GRID_BUILD_TESTS=ON ${CMAKE_ARGS:-} >/dev/null
cmake --build "$BUILD_DIR" -j2
cd "$BUILD_DIR"
ctest -j2 --output-on-failure --timeout 600
cd - >/dev/null
# The installed package and the examples built against it (what a user outside this
# tree sees), then the API docs.
bash scripts/check_install.sh "$BUILD_DIR"
bash scripts/build_docs.sh "$BUILD_DIR/docs"
