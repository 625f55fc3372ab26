#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Builds the API reference with Doxygen (docs/Doxyfile) and fails on any warning.
#   bash scripts/build_docs.sh [output folder]     (default: build/docs; HTML in <folder>/html)
set -euo pipefail
cd "$(dirname "$0")/.."
command -v doxygen >/dev/null || { echo "build_docs: doxygen not installed (scripts/install_deps.sh)" >&2; exit 1; }
out=${1:-build/docs}
mkdir -p "$out"
PLANAR_GRID_DOCS_OUTPUT=$(cd "$out" && pwd)
PLANAR_GRID_VERSION=$(sed -n 's/^project(PlanarGrid VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
export PLANAR_GRID_DOCS_OUTPUT PLANAR_GRID_VERSION
log="$PLANAR_GRID_DOCS_OUTPUT/warnings.log"
rm -f "$log"
status=0
doxygen docs/Doxyfile || status=$?
if [ -s "$log" ]; then
  echo "build_docs: $(wc -l < "$log") Doxygen warning line(s):" >&2
  cat "$log" >&2
  exit 1
fi
if [ "$status" -ne 0 ]; then
  echo "build_docs: doxygen failed (exit $status)" >&2
  exit "$status"
fi
echo "build_docs: $PLANAR_GRID_DOCS_OUTPUT/html/index.html (no warnings)"
