#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs every PlanarGrid dependency from Debian packages. Idempotent; prints nothing
# when everything is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libpcl-dev libeigen3-dev libflann-dev
  libopencv-dev libvtk9-dev
  libyaml-cpp-dev nlohmann-json3-dev
  liboctomap-dev libnanoflann-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libdynamicedt3d-dev       # OctoMap's distance transform, the peer of bench_map_queries
  xvfb xauth clang-format git
  doxygen
  help2man                  # the programs' manual pages (cmake/PlanarGridManPages.cmake)
  lintian                   # scripts/check_install.sh checks the Debian package with it
  debootstrap               # scripts/check_clean_system.sh: the package on a clean Debian
  python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest mypy
  python3-open3d            # the Python examples and their tests (Open3D loads the scan)
  python3-distributed       # planar_grid.distributed and planar_grid_batch (Dask)
  # ROS 1 bag input (optional; off in a build without them)
  librosbag-storage-dev libsensor-msgs-dev libgeometry-msgs-dev libtf2-msgs-dev
  libstd-msgs-dev
  # The ROS 1 node (optional; not built without them) and its test: a rosmaster, rosbag
  # play and rospy
  libroscpp-dev libtf2-ros-dev libmessage-filters-dev libvisualization-msgs-dev
  libnav-msgs-dev libstd-srvs-dev
  python3-genmsg python3-gencpp ros-std-msgs  # octomap_msgs/Octomap's header, generated
  # dynamic_reconfigure: the server's headers and the .cfg generator
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  python3-rosmaster python3-rospy python3-rosbag python3-rosgraph python3-roslaunch python3-yaml
  python3-std-srvs python3-visualization-msgs python3-nav-msgs python3-sensor-msgs
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
