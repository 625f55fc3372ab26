#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Checks the installed package, as a user outside the build tree finds it:
# `cmake --install` of a build into a temporary
# prefix, then the examples project (examples/) configured with CMAKE_PREFIX_PATH=<prefix>
# only (never the build tree), built, and run on a real PCL scan; the same example built
# with pkg-config and the installed planar_grid.pc alone, and a pipeline run (every module
# and the ROS bag input's libraries) linked with it; an installed tool runs and
# prints its version; an unknown COMPONENT fails with a clear message. Works for static
# and shared (BUILD_SHARED_LIBS) builds.
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
         include/planar_grid/segmentation/impl/sac_multi_plane_segmentation_detail.hpp \
         bin/planar_grid_pipeline; do
  [ -e "$prefix/$f" ] || { echo "check_install: $f was not installed" >&2; exit 1; }
done
"$prefix/bin/planar_grid_pipeline" --list-stages >/dev/null
version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$BUILD_DIR/CMakeCache.txt")
[ "$("$prefix/bin/planar_grid_pipeline" --version)" = "planar_grid_pipeline $version" ] \
  || { echo "check_install: planar_grid_pipeline --version does not print $version" >&2; exit 1; }

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
for example in segment_planes approximate_cuboids filter_features custom_point_filters; do
  echo "check_install: $example $CLOUD"
  "$work/examples/$example" "$CLOUD"
done

# The same example with pkg-config and the installed planar_grid.pc only: its Cflags and
# Libs (static libraries: every dependency; shared: ours and those of our public headers)
# plus pcl_io, which the example itself uses.
pc_dir="$prefix/lib/pkgconfig"
[ -f "$pc_dir/planar_grid.pc" ] || { echo "check_install: planar_grid.pc was not installed" >&2; exit 1; }
export PKG_CONFIG_PATH="$pc_dir"
[ "$(pkg-config --modversion planar_grid)" = "$version" ] \
  || { echo "check_install: planar_grid.pc does not give version $version" >&2; exit 1; }
echo "check_install: building examples/segment_planes.cpp with pkg-config planar_grid"
# shellcheck disable=SC2046  # pkg-config's output is a list of words
g++ -std=c++17 -O1 -Wall -o "$work/segment_planes_pc" examples/segment_planes.cpp \
  $(pkg-config --cflags --libs planar_grid pcl_io) >"$work/pc_build.log" 2>&1 \
  || { cat "$work/pc_build.log" >&2; pkg-config --cflags --libs planar_grid >&2; exit 1; }
if grep -q "warning:" "$work/pc_build.log"; then
  cat "$work/pc_build.log" >&2
  echo "check_install: the pkg-config build has warnings" >&2
  exit 1
fi
# pkg-config gives no run path: shared libraries in a prefix outside the loader's are
# found through LD_LIBRARY_PATH (or the program's own -Wl,-rpath).
LD_LIBRARY_PATH="$prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
  "$work/segment_planes_pc" "$CLOUD" >"$work/pc_run.log"
"$work/examples/segment_planes" "$CLOUD" >"$work/cmake_run.log"
cmp -s "$work/pc_run.log" "$work/cmake_run.log" \
  || { diff "$work/pc_run.log" "$work/cmake_run.log" >&2; echo "check_install: the pkg-config build prints other results" >&2; exit 1; }
# One module's own file: the segmentation needs neither VTK nor OpenCV nor the map.
pc_libs=$(pkg-config --libs planar_grid_segmentation)
case "$pc_libs" in
  *vtk* | *opencv* | *planar_grid_map* | *planar_grid_pipeline*)
    echo "check_install: planar_grid_segmentation.pc pulls in more than it needs: $pc_libs" >&2
    exit 1 ;;
esac
echo "check_install: building examples/segment_planes.cpp with pkg-config planar_grid_segmentation"
# shellcheck disable=SC2046
g++ -std=c++17 -O1 -Wall -o "$work/segment_planes_pc1" examples/segment_planes.cpp \
  $(pkg-config --cflags --libs planar_grid_segmentation pcl_io) >"$work/pc1_build.log" 2>&1 \
  || { cat "$work/pc1_build.log" >&2; exit 1; }
LD_LIBRARY_PATH="$prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
  "$work/segment_planes_pc1" "$CLOUD" >"$work/pc1_run.log"
cmp -s "$work/pc1_run.log" "$work/cmake_run.log" \
  || { echo "check_install: the planar_grid_segmentation build prints other results" >&2; exit 1; }
# A pipeline run through the same flags: the pipeline pulls in every module, the stage
# registry and the frame sources (the ROS bag one too when built), so with static
# libraries the link needs every dependency in Libs (shared: --static adds Requires.private
# and Libs.private, which must resolve too).
cat >"$work/run_pipeline.cpp" <<'CPP'
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <iostream>

int
main(int argc, char** argv)
{
  if (argc != 2)
    return 2;
  const std::string yaml = std::string("input:\n  type: pcd_files\n  files: ") + argv[1]
                           + "\n  poses: {format: none}\npipeline:\n"
                             "  - type: voxel_grid\n    params: {leaf_size_m: 0.05}\n";
  planar_grid::PipelineRunner runner(
    planar_grid::parsePipelineConfig(yaml, "run_pipeline.yaml", "."));
  const planar_grid::RunReport report = runner.run();
  std::cout << report.frames << " frame; ROS bags "
            << (planar_grid::rosBagSupported() ? "on" : "off") << "\n";
  return report.frames == 1 ? 0 : 1;
}
CPP
pc_flags=(--libs)
grep -q '^BUILD_SHARED_LIBS:BOOL=ON' "$BUILD_DIR/CMakeCache.txt" && pc_flags=(--static --libs)
echo "check_install: linking a pipeline run with pkg-config ${pc_flags[*]} planar_grid"
# shellcheck disable=SC2046  # pkg-config's output is a list of words
g++ -std=c++17 -O1 -Wall -o "$work/run_pipeline_pc" "$work/run_pipeline.cpp" \
  $(pkg-config --cflags planar_grid) $(pkg-config "${pc_flags[@]}" planar_grid) \
  >"$work/pc_pipeline.log" 2>&1 \
  || { cat "$work/pc_pipeline.log" >&2; pkg-config "${pc_flags[@]}" planar_grid >&2; exit 1; }
LD_LIBRARY_PATH="$prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
  "$work/run_pipeline_pc" "$CLOUD" \
  || { echo "check_install: the pipeline built with pkg-config does not run" >&2; exit 1; }
unset PKG_CONFIG_PATH

# The Python module, when the build has it: installed, and imported from the prefix alone
# (the libraries are linked into it; nothing comes from the build tree).
if grep -q '^PLANAR_GRID_BUILD_PYTHON:BOOL=ON' "$BUILD_DIR/CMakeCache.txt"; then
  python=$(sed -n 's/^Python3_EXECUTABLE:FILEPATH=//p' "$BUILD_DIR/CMakeCache.txt")
  module_dir="$prefix/$(sed -n 's/^PLANAR_GRID_PYTHON_INSTALL_DIR:STRING=//p' "$BUILD_DIR/CMakeCache.txt")"
  ls "$module_dir"/planar_grid*.so >/dev/null 2>&1 \
    || { echo "check_install: the Python module was not installed in $module_dir" >&2; exit 1; }
  echo "check_install: import planar_grid from $module_dir"
  (cd "$work" && PYTHONPATH="$module_dir" "$python" -c "
import sys
import numpy as np
import planar_grid as pg
assert pg.__file__.startswith(sys.argv[1]), pg.__file__
uv = np.stack(np.meshgrid(np.arange(0, 2, 0.05), np.arange(0, 2, 0.05)), -1).reshape(-1, 2)
planes = pg.SACMultiPlaneSegmentation(min_inliers=100).segment(np.column_stack([uv, np.ones(len(uv))]))
assert len(planes) == 1, planes
" "$module_dir")
fi

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
