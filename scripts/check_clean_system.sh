#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs the Debian package on a clean Debian system, as on a new user's machine, and
# uses it there. The system is a minimal Debian of this machine's release, made by
# debootstrap in a temporary folder; apt installs the package into it with
# `apt-get install ./planar-grid_*.deb`, so every Depends and Recommends comes from
# Debian's archive and nothing from this machine. Then, inside it (chroot), in an empty
# environment, outside any source tree:
#   - planar_grid_pipeline from PATH maps PCL's office1 scan with its default outputs,
#     the snapshots included (the tool starts Xvfb itself: no display there);
#   - planar_grid_viewer renders the map to a PNG;
#   - /usr/bin/python3 imports planar_grid with no PYTHONPATH, loads the map and runs the
#     pipeline; planar_grid_batch --version runs;
#   - with g++ installed as a C++ user has it, the examples build with
#     find_package(PlanarGrid) and no CMAKE_PREFIX_PATH, without warnings, and run on the
#     scan; pkg-config finds planar_grid.
# Needs root and debootstrap. The chroot's /proc is mounted in a private mount namespace
# (unshare), so no mount outlives the script; the folder is removed at the end.
#   bash scripts/check_clean_system.sh [build folder | planar-grid_*.deb]
# (default: $BUILD_DIR, else build/; a build folder is packaged with cpack first).
# The archive is the first of this machine's apt sources (PLANAR_GRID_DEBIAN_MIRROR sets
# another); the scan comes from PLANAR_GRID_DATA_DIR (default ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
ARG=${1:-${BUILD_DIR:-build}}
DATA_DIR=${PLANAR_GRID_DATA_DIR:-../shared/data}
CLOUD="$DATA_DIR/pcl_clouds/office1.pcd"

fail() {
  echo "check_clean_system: $*" >&2
  exit 1
}
[ "$(id -u)" = 0 ] || fail "needs root (debootstrap and chroot)"
command -v debootstrap >/dev/null || fail "needs debootstrap (apt-get install debootstrap)"
command -v unshare >/dev/null || fail "needs unshare (util-linux)"
[ -f "$CLOUD" ] || fail "$CLOUD not found"

work=$(mktemp -d "${TMPDIR:-/tmp}/planar_grid_clean.XXXXXX")
root="$work/root"
cleanup() {
  # Nothing is mounted outside the namespace the chroot ran in, which has ended; refuse
  # to remove a folder that still holds a mount all the same.
  if findmnt -rn -o TARGET | grep -q "^$root/"; then
    echo "check_clean_system: $root still holds mounts; left in place" >&2
  else
    rm -rf "$work"
  fi
}
trap cleanup EXIT

if [[ "$ARG" == *.deb ]]; then
  deb=$(realpath "$ARG")
  [ -f "$deb" ] || fail "$ARG not found"
else
  [ -f "$ARG/CPackConfig.cmake" ] || fail "$ARG is not a configured build folder"
  echo "check_clean_system: cpack -G DEB"
  cpack -G DEB --config "$ARG/CPackConfig.cmake" -B "$work/deb" >"$work/cpack.log" 2>&1 \
    || { cat "$work/cpack.log" >&2; fail "cpack -G DEB failed"; }
  deb=$(ls "$work"/deb/planar-grid_*.deb)
fi
version=$(dpkg-deb -f "$deb" Version)

# This machine's release and archive.
# shellcheck disable=SC1091  # os-release is the system's
suite=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
[ -n "$suite" ] || fail "/etc/os-release names no release (VERSION_CODENAME)"
mirror=${PLANAR_GRID_DEBIAN_MIRROR:-}
if [ -z "$mirror" ]; then
  mirror=$(cat /etc/apt/sources.list.d/*.sources 2>/dev/null | sed -n 's/^URIs: *//p' \
           | tr ' ' '\n' | grep -v security | head -1 || true)
  [ -n "$mirror" ] || mirror=$(sed -n 's/^deb \(\[[^]]*\] \)\{0,1\}\([^ ]*\) .*/\2/p' \
                                 /etc/apt/sources.list 2>/dev/null | head -1 || true)
  mirror=${mirror:-http://deb.debian.org/debian}
fi

echo "check_clean_system: debootstrap --variant=minbase $suite from $mirror"
start=$SECONDS
debootstrap --variant=minbase --cache-dir=/var/cache/apt/archives "$suite" "$root" "$mirror" >"$work/debootstrap.log" 2>&1 \
  || { tail -20 "$work/debootstrap.log" >&2; fail "debootstrap failed"; }
echo "check_clean_system: a minimal $suite in $((SECONDS - start)) s, $(du -sm "$root" | cut -f1) MB"
# The same archive sections as this machine (its updates and security suites too), so
# that the package's versioned dependencies resolve as they did here.
if ls /etc/apt/sources.list.d/*.sources >/dev/null 2>&1 || [ -s /etc/apt/sources.list ]; then
  rm -f "$root/etc/apt/sources.list"
  cp /etc/apt/sources.list.d/*.sources "$root/etc/apt/sources.list.d/" 2>/dev/null || true
  [ ! -s /etc/apt/sources.list ] || cp /etc/apt/sources.list "$root/etc/apt/sources.list"
fi
cp /etc/resolv.conf "$root/etc/resolv.conf"

# What the user brings: the package, a scan and a configuration, the examples' sources.
mkdir -p "$root/home/user/data"
cp "$deb" "$root/home/user/"
cp "$CLOUD" "$root/home/user/data/office1.pcd"
sed "s|^  files: .*|  files: /home/user/data/office1.pcd|" config/office1.yaml \
  >"$root/home/user/office1.yaml"
cp -r examples "$root/home/user/examples"

cat >"$root/home/user/check.sh" <<'CHECK'
set -euo pipefail
cd /home/user
say() { echo "check_clean_system: $*"; }
fail() { echo "check_clean_system: $*" >&2; exit 1; }
export DEBIAN_FRONTEND=noninteractive
apt-get update -q >apt_update.log 2>&1 || { cat apt_update.log >&2; fail "apt-get update failed"; }
start=$SECONDS
deb=$(ls /home/user/planar-grid_*.deb)
# No fsync per file: the system is thrown away after the check.
apt-get install -y -q -o Dpkg::Options::=--force-unsafe-io "$deb" >apt_install.log 2>&1 \
  || { tail -30 apt_install.log >&2; fail "apt-get install of the package failed"; }
say "apt-get install ./$(basename "$deb"): $(grep -oE '[0-9]+ newly installed' apt_install.log), $(grep -oE 'Need to get [^ ]+ [kMG]?B(/[^ ]+ [kMG]?B)?' apt_install.log || echo 'nothing to fetch'), $((SECONDS - start)) s"
dpkg-query -W -f='${Status} ${Version}\n' planar-grid | grep -q "^install ok installed $1\$" \
  || fail "dpkg does not list planar-grid $1 as installed"
user_env=(env -i PATH=/usr/local/bin:/usr/bin:/bin HOME=/home/user LANG=C.UTF-8)

[ "$("${user_env[@]}" planar_grid_pipeline --version)" = "planar_grid_pipeline $1" ] \
  || fail "planar_grid_pipeline --version does not print $1"
"${user_env[@]}" planar_grid_pipeline --config office1.yaml --output run -q >run.log 2>&1 \
  || { cat run.log >&2; fail "planar_grid_pipeline failed on office1"; }
for f in map.pgmap report.json snapshot.png cuboids.png; do
  [ -s "run/$f" ] || fail "planar_grid_pipeline wrote no run/$f"
done
say "planar_grid_pipeline mapped office1: $(ls run | wc -l) outputs, snapshots included"
"${user_env[@]}" planar_grid_viewer run/map.pgmap --snapshot viewer.png >viewer.log 2>&1 \
  || { cat viewer.log >&2; fail "planar_grid_viewer failed"; }
[ -s viewer.png ] || fail "planar_grid_viewer wrote no snapshot"
say "planar_grid_viewer rendered the map ($(du -k viewer.png | cut -f1) KiB PNG)"

"${user_env[@]}" /usr/bin/python3 -c "
import planar_grid as pg
assert pg.__file__.startswith('/usr/lib/python3/dist-packages/'), pg.__file__
m = pg.PlanarGridMap.load('run/map.pgmap')
result = pg.run_pipeline('office1.yaml', write_outputs=False)
assert result.report['frames'] == 1 and len(result.plane_models) >= 3, result.plane_models
print('check_clean_system: python3 imports', pg.__file__, 'loads the map and maps office1:',
      len(result.plane_models), 'planes')
" || fail "the Python module failed"
[ "$("${user_env[@]}" planar_grid_batch --version)" = "planar_grid_batch $1" ] \
  || fail "planar_grid_batch --version does not print $1"
say "planar_grid_batch --version"

apt-get install -y -q -o Dpkg::Options::=--force-unsafe-io g++ >apt_gxx.log 2>&1 || { tail -20 apt_gxx.log >&2; fail "apt-get install g++ failed"; }
[ "$("${user_env[@]}" pkg-config --modversion planar_grid)" = "$1" ] \
  || fail "pkg-config does not find planar_grid $1"
"${user_env[@]}" cmake -S examples -B examples-build -DCMAKE_BUILD_TYPE=Release \
  >configure.log 2>&1 || { cat configure.log >&2; fail "the examples do not configure"; }
grep -q '^PlanarGrid_DIR:PATH=/usr/lib/cmake/PlanarGrid$' examples-build/CMakeCache.txt \
  || fail "find_package(PlanarGrid) did not find /usr/lib/cmake/PlanarGrid"
"${user_env[@]}" cmake --build examples-build -j2 >build.log 2>&1 \
  || { cat build.log >&2; fail "the examples do not build"; }
if grep -q "warning:" build.log; then
  grep -B2 -A4 "warning:" build.log >&2
  fail "the examples build with warnings"
fi
for example in segment_planes approximate_cuboids filter_features custom_point_filters; do
  "${user_env[@]}" "examples-build/$example" data/office1.pcd >"$example.log" 2>&1 \
    || { cat "$example.log" >&2; fail "example $example failed"; }
done
say "the examples built with find_package(PlanarGrid) from /usr and ran; pkg-config finds planar_grid $1"
CHECK

echo "check_clean_system: installing $(basename "$deb") there and using it"
# The chroot's apt keeps its downloads in this machine's archive cache (bound in), so
# that a package fetched once is not fetched again; what is installed stays the chroot's.
# shellcheck disable=SC2016  # the inner script expands its own arguments
unshare --mount --propagation private /bin/bash -c '
  set -e
  mount -t proc proc "$1/proc"
  mount --bind /var/cache/apt/archives "$1/var/cache/apt/archives"
  chroot "$1" /bin/bash /home/user/check.sh "$2"
' check "$root" "$version"
echo "check_clean_system: OK"
