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
# Then the Debian package (cpack -G DEB, cmake/PlanarGridPackaging.cmake): extracted with
# dpkg-deb -x into a temporary root, its tools run, the examples build against
# <root>/usr (from /usr instead when the package is installed for real, below), its
# Python module maps the scan, and every package it Depends on or
# Recommends is installed or installable here (apt-cache policy; and apt-get install -s,
# a simulation, resolves them). As root on CI (CI=true) or with PLANAR_GRID_APT_INSTALL=1,
# it is then installed for real with apt-get, used from /usr, and purged.
#   bash scripts/check_install.sh [build folder]    (default: $BUILD_DIR, else build/)
# The scan comes from PLANAR_GRID_DATA_DIR (default ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-${BUILD_DIR:-build}}
DATA_DIR=${PLANAR_GRID_DATA_DIR:-../shared/data}
CLOUD="$DATA_DIR/pcl_clouds/office1.pcd"
[ -f "$CLOUD" ] || { echo "check_install: $CLOUD not found" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/planar_grid_install.XXXXXX")
apt_installed=false
# purge_package: removes the planar-grid this script installed.
purge_package() {
  apt-get purge -y -q planar-grid >"$work/apt_purge.log" 2>&1 \
    || { cat "$work/apt_purge.log" >&2; echo "check_install: apt-get purge planar-grid failed" >&2; return 1; }
  apt_installed=false
}
cleanup() {
  # A package this script installed leaves with it, whatever ended the script.
  if $apt_installed; then purge_package || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
prefix="$work/prefix"

echo "check_install: cmake --install $BUILD_DIR --prefix $prefix"
cmake --install "$BUILD_DIR" --prefix "$prefix" >/dev/null
for f in lib/cmake/PlanarGrid/PlanarGridConfig.cmake \
         lib/cmake/PlanarGrid/PlanarGridConfigVersion.cmake \
         lib/cmake/PlanarGrid/PlanarGridTargets.cmake \
         include/planar_grid/segmentation/sac_multi_plane_segmentation.h \
         include/planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp \
         include/planar_grid/segmentation/impl/sac_multi_plane_segmentation_detail.hpp \
         include/planar_grid/surface/rectangle_merge.h \
         bin/planar_grid_pipeline; do
  [ -e "$prefix/$f" ] || { echo "check_install: $f was not installed" >&2; exit 1; }
done
version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$BUILD_DIR/CMakeCache.txt")
# Where the .pc files go, relative to the prefix (cmake/PlanarGridPkgConfig.cmake).
pc_subdir=$(sed -n 's/^PLANAR_GRID_PKGCONFIG_INSTALL_DIR:STRING=//p' "$BUILD_DIR/CMakeCache.txt")
[ -n "$pc_subdir" ] || { echo "check_install: $BUILD_DIR has no PLANAR_GRID_PKGCONFIG_INSTALL_DIR" >&2; exit 1; }

# check_tools PREFIX: the installed pipeline tool lists its stages and prints the version.
check_tools() {
  local prefix=$1
  "$prefix/bin/planar_grid_pipeline" --list-stages >/dev/null
  [ "$("$prefix/bin/planar_grid_pipeline" --version)" = "planar_grid_pipeline $version" ] \
    || { echo "check_install: $prefix/bin/planar_grid_pipeline --version does not print $version" >&2; return 1; }
}

# check_examples PREFIX FOLDER: the examples, configured in FOLDER against PREFIX only (no
# package registry, no build tree), built without warnings and run on the scan.
check_examples() {
  local prefix=$1 dir=$2
  echo "check_install: building examples/ against $prefix"
  # /usr is where CMake looks by itself: no CMAKE_PREFIX_PATH then.
  local prefix_path=(-DCMAKE_PREFIX_PATH="$prefix")
  [ "$prefix" != /usr ] || prefix_path=()
  cmake -S examples -B "$dir" -DCMAKE_BUILD_TYPE=Release \
    "${prefix_path[@]}" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF >"$dir.configure.log" \
    || { cat "$dir.configure.log" >&2; return 1; }
  local found_dir
  found_dir=$(sed -n 's/^PlanarGrid_DIR:PATH=//p' "$dir/CMakeCache.txt")
  case "$found_dir" in
    "$prefix"/*) ;;
    *) echo "check_install: PlanarGrid was found at '$found_dir', not in $prefix" >&2; return 1 ;;
  esac
  cmake --build "$dir" -j2 >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  if grep -q "warning:" "$dir.build.log"; then
    grep -B2 -A4 "warning:" "$dir.build.log" >&2
    echo "check_install: the examples build with warnings" >&2
    return 1
  fi
  local example
  for example in segment_planes approximate_cuboids filter_features custom_point_filters; do
    echo "check_install: $example $CLOUD"
    "$dir/$example" "$CLOUD"
  done
}

check_tools "$prefix"
check_examples "$prefix" "$work/examples"

# The same example with pkg-config and the installed planar_grid.pc only: its Cflags and
# Libs (static libraries: every dependency; shared: ours and those of our public headers)
# plus pcl_io, which the example itself uses.
pc_dir="$prefix/$pc_subdir"
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

# check_python MODULE_DIR: the Python module imported from MODULE_DIR alone (the libraries
# are linked into it; nothing comes from the build tree).
check_python() {
  local module_dir=$1
  ls "$module_dir"/planar_grid/_planar_grid*.so >/dev/null 2>&1 \
    || { echo "check_install: the Python module was not installed in $module_dir/planar_grid" >&2; return 1; }
  echo "check_install: import planar_grid from $module_dir"
  (cd "$work" && PYTHONPATH="$module_dir" "$python" -c "
import sys
import numpy as np
import planar_grid as pg
assert pg.__file__.startswith(sys.argv[1]), pg.__file__
uv = np.stack(np.meshgrid(np.arange(0, 2, 0.05), np.arange(0, 2, 0.05)), -1).reshape(-1, 2)
planes = pg.SACMultiPlaneSegmentation(min_inliers=100).segment(np.column_stack([uv, np.ones(len(uv))]))
assert len(planes) == 1, planes
import planar_grid.distributed as pgd
assert pgd.split_frames(0, 112, 4)[-1] == (84, 112)
" "$module_dir")
}

# check_batch PREFIX: the installed planar_grid_batch finds the installed package by its
# own place (no PYTHONPATH) and prints the version.
check_batch() {
  local prefix=$1
  [ "$(cd "$work" && env -u PYTHONPATH "$prefix/bin/planar_grid_batch" --version)" \
    = "planar_grid_batch $version" ] \
    || { echo "check_install: $prefix/bin/planar_grid_batch --version does not print $version" >&2; return 1; }
  echo "check_install: $prefix/bin/planar_grid_batch --version"
}

has_python=false
if grep -q '^PLANAR_GRID_BUILD_PYTHON:BOOL=ON' "$BUILD_DIR/CMakeCache.txt"; then
  has_python=true
  python=$(sed -n 's/^Python3_EXECUTABLE:FILEPATH=//p' "$BUILD_DIR/CMakeCache.txt")
  python_dir=$(sed -n 's/^PLANAR_GRID_PYTHON_INSTALL_DIR:STRING=//p' "$BUILD_DIR/CMakeCache.txt")
  check_python "$prefix/$python_dir"
  check_batch "$prefix"
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
# The message is one sentence, not a CMake list ("PlanarGrid ;0.1.0").
if grep -q "PlanarGrid ;" "$work/unknown.log"; then
  cat "$work/unknown.log" >&2
  echo "check_install: the unknown-component message is a ';'-joined list" >&2
  exit 1
fi

# The Debian package of the same build (cmake/PlanarGridPackaging.cmake), checked without
# installing it: this machine's /usr stays as it was. dpkg-deb extracts it into a
# temporary root, and everything runs from <root>/usr.
if ! command -v dpkg-deb >/dev/null; then
  echo "check_install: OK (no dpkg-deb here: the Debian package was not checked)"
  exit 0
fi
echo "check_install: cpack -G DEB"
cpack -G DEB --config "$BUILD_DIR/CPackConfig.cmake" -B "$work/deb" >"$work/cpack.log" 2>&1 \
  || { cat "$work/cpack.log" >&2; echo "check_install: cpack -G DEB failed" >&2; exit 1; }
deb="$work/deb/planar-grid_${version}_$(dpkg --print-architecture).deb"
[ -f "$deb" ] || { cat "$work/cpack.log" >&2; echo "check_install: cpack wrote no $deb" >&2; exit 1; }
outside=$(dpkg-deb -c "$deb" | awk '{ print $6 }' | grep -v -e '^\./$' -e '^\./usr/' || true)
[ -z "$outside" ] || { echo "check_install: the package installs outside /usr: $outside" >&2; exit 1; }
root="$work/root"
dpkg-deb -x "$deb" "$root"
echo "check_install: $(basename "$deb"), $(du -k "$deb" | cut -f1) KiB, $(dpkg-deb -c "$deb" | grep -vc '/$') files, extracted into $root"
for f in bin/planar_grid_pipeline lib/cmake/PlanarGrid/PlanarGridConfig.cmake \
         "$pc_subdir/planar_grid.pc" include/planar_grid/version.h \
         share/man/man1/planar_grid_pipeline.1.gz share/doc/planar-grid/copyright; do
  [ -e "$root/usr/$f" ] || { echo "check_install: the package has no /usr/$f" >&2; exit 1; }
done

# Debian's package checker: no error and no warning, beyond the tags the package's own
# overrides file names with its reasons (cmake/planar-grid.lintian-overrides).
if command -v lintian >/dev/null; then
  lintian --no-cfg --fail-on error,warning "$deb" >"$work/lintian.log" 2>&1 \
    || { cat "$work/lintian.log" >&2; echo "check_install: lintian reports errors or warnings" >&2; exit 1; }
  echo "check_install: lintian: no errors or warnings ($(lintian --no-cfg --show-overrides "$deb" 2>/dev/null | grep -c '^O:') overridden tags)"
else
  echo "check_install: no lintian here: the package was not checked by it"
fi

# The tools find our libraries without LD_LIBRARY_PATH: linked in (static libraries), or
# through their run path $ORIGIN/../lib (shared ones), which points into the root.
check_tools "$root/usr"
# The examples against the package's files: here in the extracted root, or, when the
# package is installed for real below, from /usr (the same files; built once).
apt_check=false
if [ "$(id -u)" = 0 ] && { [ "${CI:-}" = true ] || [ "${PLANAR_GRID_APT_INSTALL:-0}" = 1 ]; }; then
  apt_check=true
fi
if $apt_check; then
  echo "check_install: the examples build against the package when it is installed in /usr"
else
  check_examples "$root/usr" "$work/examples-deb"
fi
# The .pc files locate their prefix from their own folder.
[ "$(PKG_CONFIG_PATH="$root/usr/$pc_subdir" pkg-config --variable=includedir planar_grid)" \
  -ef "$root/usr/include" ] \
  || { echo "check_install: the packaged planar_grid.pc does not point into its root" >&2; exit 1; }

# config/office1.yaml with the scan's path made absolute, for the packaged module and tool.
sed "s|^  files: .*|  files: $(realpath "$CLOUD")|" config/office1.yaml >"$work/office1.yaml"
# The Python module, with the interpreter the package depends on, maps the scan through the
# pipeline.
if $has_python; then
  python=/usr/bin/python3
  check_python "$root/usr/lib/python3/dist-packages"
  check_batch "$root/usr"
  echo "check_install: mapping $CLOUD with the packaged Python module"
  (cd "$work" && PYTHONPATH="$root/usr/lib/python3/dist-packages" "$python" -c "
import sys
import planar_grid as pg
result = pg.run_pipeline(sys.argv[1], write_outputs=False)
assert result.report['frames'] == 1, result.report
assert result.map is not None and len(result.plane_models) >= 3, result.plane_models
print('check_install: office1:', len(result.plane_models), 'planes,',
      result.map.memory['total_bytes'], 'bytes of map')
" "$work/office1.yaml")
fi

# Depends and Recommends: every relation (or one of its alternatives) is met by an installed
# package or by apt's candidate, at the versions asked.
satisfiable() {
  local name=$1 op=$2 wanted=$3 have
  have=$(dpkg-query -W -f='${db:Status-Abbrev} ${Version}\n' "$name" 2>/dev/null \
         | sed -n 's/^ii  *//p' | head -1)
  if [ -z "$have" ]; then
    have=$(apt-cache policy "$name" 2>/dev/null | sed -n 's/^ *Candidate: //p')
    [ -n "$have" ] && [ "$have" != "(none)" ] || return 1
  fi
  [ -z "$op" ] || dpkg --compare-versions "$have" "$op" "$wanted"
}
check_relations() {
  local field=$1 relation alternative ok name op wanted
  local -a relations alternatives
  IFS=',' read -r -a relations <<<"$(dpkg-deb -f "$deb" "$field")"
  for relation in "${relations[@]}"; do
    ok=false
    IFS='|' read -r -a alternatives <<<"$relation"
    for alternative in "${alternatives[@]}"; do
      read -r name op wanted <<<"$(tr -d '()' <<<"$alternative")"
      if satisfiable "$name" "$op" "$wanted"; then ok=true; break; fi
    done
    $ok || { echo "check_install: $field '$relation' is neither installed nor installable" >&2; return 1; }
  done
  echo "check_install: $field: ${#relations[@]} relations, each installed or installable"
}
check_relations Depends
check_relations Recommends
# And apt itself, in a simulation that changes nothing, resolves them for `apt install`.
if ! apt-get install -s "$deb" >"$work/apt_simulate.log" 2>&1 \
   || ! grep -q '^Inst planar-grid ' "$work/apt_simulate.log"; then
  cat "$work/apt_simulate.log" >&2
  echo "check_install: apt would not install the package" >&2
  exit 1
fi
echo "check_install: apt-get install -s: $(grep -c '^Inst ' "$work/apt_simulate.log") packages to install, planar-grid among them"
# The dependencies' files that the CMake package and the .pc files name by path, and the
# .pc modules that the .pc files require, come from packages that the package depends on
# or recommends.
declared=" $(dpkg-deb -f "$deb" Depends Recommends | sed -e 's/^[A-Za-z]*: //' -e 's/([^)]*)//g' | tr ',|\n' '   ') "
mapfile -t named < <(grep -ohE '/usr/[^ ;"()>]+\.(so|a)\b' "$root"/usr/lib/cmake/PlanarGrid/*.cmake \
                       "$root/usr/$pc_subdir"/*.pc | sort -u)
export PKG_CONFIG_PATH="$root/usr/$pc_subdir"
for pc in "$root/usr/$pc_subdir"/*.pc; do
  pkg-config --print-requires --print-requires-private "$(basename "$pc" .pc)"
done | awk '$1 !~ /^planar_grid/ { print $1 }' | sort -u >"$work/pc_requires.txt"
while read -r module; do
  named+=("$(realpath "$(pkg-config --variable=pcfiledir "$module")/$module.pc")")
done <"$work/pc_requires.txt"
unset PKG_CONFIG_PATH
if [ ${#named[@]} -gt 0 ]; then
  owners=$(dpkg -S "${named[@]}" 2>"$work/dpkg_S.log") \
    || { cat "$work/dpkg_S.log" >&2; echo "check_install: the package names files that no Debian package holds" >&2; exit 1; }
  while read -r owner; do
    case "$declared" in
      *" $owner "*) ;;
      *) echo "check_install: the package uses files of $owner, which it neither depends on nor recommends" >&2; exit 1 ;;
    esac
  done < <(cut -d: -f1 <<<"$owners" | sort -u)
fi
echo "check_install: the ${#named[@]} files of other packages it names (the .pc files of $(wc -l <"$work/pc_requires.txt") modules among them) come from packages it depends on or recommends"

# The package installed for real (`apt-get install ./planar-grid_*.deb`, as a user does),
# then used as a user outside this tree finds it: the tools on PATH, the CMake package
# with no CMAKE_PREFIX_PATH, pkg-config with no PKG_CONFIG_PATH, the Python module with
# no PYTHONPATH; then purged, leaving no file of it behind. It changes /usr, so it runs
# only as root, on CI (CI=true) or when PLANAR_GRID_APT_INSTALL=1 asks for it, and never
# over an installed planar-grid.
apt_install_check() {
  echo "check_install: apt-get install $deb"
  apt_installed=true
  apt-get install -y -q "$deb" >"$work/apt_install.log" 2>&1 \
    || { cat "$work/apt_install.log" >&2; echo "check_install: apt-get install of the package failed" >&2; return 1; }
  dpkg-query -W -f='${Status} ${Version}\n' planar-grid | grep -q "^install ok installed $version\$" \
    || { echo "check_install: dpkg does not list planar-grid $version as installed" >&2; return 1; }
  mapfile -t installed_files < <(dpkg -L planar-grid)
  local clean_env=(env -i PATH=/usr/bin:/bin HOME="$work" LANG=C.UTF-8)
  check_tools /usr
  mkdir -p "$work/apt_run"
  (cd "$work" && "${clean_env[@]}" planar_grid_pipeline --config "$work/office1.yaml" \
     --output "$work/apt_run" --no-snapshot -q) >"$work/apt_run.log" 2>&1 \
    || { cat "$work/apt_run.log" >&2; echo "check_install: the installed planar_grid_pipeline failed on office1" >&2; return 1; }
  [ -s "$work/apt_run/map.pgmap" ] && [ -s "$work/apt_run/report.json" ] \
    || { echo "check_install: the installed pipeline wrote no map of office1" >&2; return 1; }
  echo "check_install: /usr/bin/planar_grid_pipeline mapped office1 ($(du -k "$work/apt_run/map.pgmap" | cut -f1) KiB map)"
  check_examples /usr "$work/examples-apt"
  [ "$("${clean_env[@]}" pkg-config --modversion planar_grid)" = "$version" ] \
    || { echo "check_install: pkg-config does not find planar_grid $version in /usr" >&2; return 1; }
  if $has_python; then
    (cd "$work" && "${clean_env[@]}" /usr/bin/python3 -c "
import planar_grid as pg
assert pg.__file__.startswith('/usr/lib/python3/dist-packages/'), pg.__file__
m = pg.PlanarGridMap.load('$work/apt_run/map.pgmap')
assert m.memory['total_bytes'] > 0
print('check_install: /usr/bin/python3 imports', pg.__file__, 'and loads the map')
")
    check_batch /usr
  fi
  purge_package || return 1
  local f left=()
  for f in "${installed_files[@]}"; do
    [ -d "$f" ] || [ ! -e "$f" ] || left+=("$f")
  done
  [ ${#left[@]} -eq 0 ] || { echo "check_install: files left after the purge: ${left[*]}" >&2; return 1; }
  echo "check_install: installed ${#installed_files[@]} paths, used, purged; none left"
}
if $apt_check; then
  if dpkg-query -W -f='${Status}' planar-grid 2>/dev/null | grep -q 'ok installed'; then
    echo "check_install: planar-grid is already installed here: the package was not installed over it" >&2
    exit 1
  fi
  apt_install_check
else
  echo "check_install: the package was not installed (run as root with CI=true or PLANAR_GRID_APT_INSTALL=1)"
fi
echo "check_install: OK"
