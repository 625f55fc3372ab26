#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Checks the installed package (issue #9): `cmake --install` of a build into a temporary
# prefix, then the examples project (examples/) configured with CMAKE_PREFIX_PATH=<prefix>
# only (never the build tree), built, and run on a real PCL scan; an installed tool runs;
# an unknown COMPONENT fails with a clear message.
#   bash scripts/check_install.sh [build folder]    (default: $BUILD_DIR, else build/)
# The scan comes from PLANAR_GRID_DATA_DIR (default ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-${BUILD_DIR:-build}}
DATA_DIR=${PLANAR_GRID_DATA_DIR:-../shared/data}
CLOUD="$DATA_DIR/pcl_clouds/office1.pcd"
[ -f "$CLOUD" ] || { echo "check_install: $CLOUD not found" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/planar_grid_install.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"

echo "check_install: cmake --install $BUILD_DIR --prefix $prefix"
cmake --install "$BUILD_DIR" --prefix "$prefix" >/dev/null
for f in lib/cmake/PlanarGrid/PlanarGridConfig.cmake \
         lib/cmake/PlanarGrid/PlanarGridConfigVersion.cmake \
         lib/cmake/PlanarGrid/PlanarGridTargets.cmake \
         include/planar_grid/segmentation/sac_multi_plane_segmentation.h \
         include/planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp \
         bin/planar_grid_pipeline; do
  [ -e "$prefix/$f" ] || { echo "check_install: $f was not installed" >&2; exit 1; }
done
"$prefix/bin/planar_grid_pipeline" --list-stages >/dev/null

# The examples, against the prefix only (no package registry, no build tree).
echo "check_install: building examples/ against the installed package"
cmake -S examples -B "$work/examples" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF >"$work/configure.log" \
  || { cat "$work/configure.log" >&2; exit 1; }
found_dir=$(sed -n 's/^PlanarGrid_DIR:PATH=//p' "$work/examples/CMakeCache.txt")
case "$found_dir" in
  "$prefix"/*) ;;
  *) echo "check_install: PlanarGrid was found at '$found_dir', not in $prefix" >&2; exit 1 ;;
esac
cmake --build "$work/examples" -j2 >"$work/build.log" 2>&1 || { cat "$work/build.log" >&2; exit 1; }
if grep -q "warning:" "$work/build.log"; then
  grep -B2 -A4 "warning:" "$work/build.log" >&2
  echo "check_install: the examples build with warnings" >&2
  exit 1
fi
for example in segment_planes approximate_cuboids filter_features; do
  echo "check_install: $example $CLOUD"
  "$work/examples/$example" "$CLOUD"
done

# An unknown component is an error that names the known ones.
mkdir -p "$work/unknown"
cat >"$work/unknown/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.16)
project(UnknownComponent LANGUAGES CXX)
find_package(PlanarGrid REQUIRED COMPONENTS segmentation no_such_module)
CMAKE
if cmake -S "$work/unknown" -B "$work/unknown/build" -DCMAKE_PREFIX_PATH="$prefix" \
     >"$work/unknown.log" 2>&1; then
  echo "check_install: find_package accepted an unknown component" >&2
  exit 1
fi
grep -q "Unknown PlanarGrid component 'no_such_module'" "$work/unknown.log" \
  || { cat "$work/unknown.log" >&2; echo "check_install: unclear error for an unknown component" >&2; exit 1; }
echo "check_install: OK"
