# SPDX-License-Identifier: BSD-3-Clause
# The Debian package planar-grid, built by CPack from what `cmake --install` installs:
#
#   cmake --build build && cpack -G DEB --config build/CPackConfig.cmake -B build/deb
#   sudo apt install ./build/deb/planar-grid_<version>_amd64.deb
#
# One package under /usr: the tools and their manual pages, the ROS node (when built),
# the Python module in /usr/lib/python3/dist-packages, and the development files
# (headers, the static or shared libraries, the CMake package in
# /usr/lib/cmake/PlanarGrid, the pkg-config files in /usr/lib/<multiarch>/pkgconfig).
# Depends: the run-time libraries of the installed programs and of the Python module, as
# dpkg-shlibdeps (dpkg-dev) finds them, plus the Python 3 minor version the module was
# built for and numpy. Recommends: the -dev packages the CMake package and the .pc files
# look for, so that a plain `apt install` can build against it and
# `--no-install-recommends` gives the programs alone. scripts/check_install.sh builds the
# package, checks it extracted into a temporary root and with lintian, and on CI installs
# it with apt, uses it and purges it.
# Include it once, at the end of the top-level CMakeLists.txt, after every install() rule.

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME planar-grid)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "The PlanarGrid authors")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "planar surface-based 3D mapping from stereo (PCL-style C++17 library)")
# Lines of at most 79 characters with the space the control file puts before each, as
# dpkg and apt show them (lintian: extended-description-line-too-long).
set(CPACK_PACKAGE_DESCRIPTION
    "PlanarGrid builds 3D occupancy maps for mobile robots from stereo cameras,
with plane-aligned cuboid cells instead of cubic voxels. This package holds
the tools (planar_grid_pipeline, planar_grid_viewer, planar_grid_eval, ...)
with their manual pages, the Python module planar_grid, and the headers,
libraries, CMake package (find_package(PlanarGrid)) and pkg-config files to
build against the library.")
set(CPACK_RESOURCE_FILE_LICENSE ${PROJECT_SOURCE_DIR}/LICENSE)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
# The executables and the Python module without their symbol tables (Release builds
# carry no debug information to keep).
set(CPACK_STRIP_FILES ON)

# <name>_<version>_<architecture>.deb, the name Debian's tools expect.
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# The licence and the SPDX headers name "The PlanarGrid authors" and no address.
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "The PlanarGrid authors")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)

set(_pg_depends "")
if(PLANAR_GRID_BUILD_PYTHON)
  # The module's file name carries its interpreter's ABI (cpython-3XY): that minor
  # version only. numpy is imported by the module (pybind11's arrays) at run time.
  math(EXPR _pg_python_next "${Python3_VERSION_MINOR} + 1")
  list(APPEND _pg_depends
       "python3 (>= ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}~)"
       "python3 (<< ${Python3_VERSION_MAJOR}.${_pg_python_next})" python3-numpy)
endif()
string(REPLACE ";" ", " CPACK_DEBIAN_PACKAGE_DEPENDS "${_pg_depends}")

# What find_package(PlanarGrid) and the .pc files need beyond the package itself: the
# dependencies' headers, CMake configs, .pc files and unversioned .so links (the Debian
# -dev packages of what the modules link; scripts/install_deps.sh installs the same ones).
# scripts/check_install.sh checks that every file and .pc module the package names by
# path or by name comes from one of these.
set(_pg_recommends libpcl-dev libeigen3-dev libopencv-dev libyaml-cpp-dev nlohmann-json3-dev
    liboctomap-dev libnanoflann-dev)
if(PLANAR_GRID_BUILD_VIEWER)
  # The visualization module links VTK and X11 (its .pc file requires x11).
  list(APPEND _pg_recommends libvtk9-dev libx11-dev)
  # Debian's VTK renders offscreen only through an X server: on a machine without a
  # display the tools' snapshots (on by default) start Xvfb themselves.
  list(APPEND _pg_recommends xvfb xauth)
endif()
if(PLANAR_GRID_HAVE_ROS_BAG)
  # The bag library's ROS libraries, linked by their files (src/ros_bag/CMakeLists.txt).
  list(APPEND _pg_recommends librosbag-storage-dev libroscpp-core-dev libconsole-bridge-dev)
endif()
if(PLANAR_GRID_BUILD_PYTHON)
  # planar_grid.distributed and its command planar_grid_batch (Dask); the rest of the
  # package runs without it.
  list(APPEND _pg_recommends python3-distributed)
endif()
list(APPEND _pg_recommends cmake pkg-config)
string(REPLACE ";" ", " CPACK_DEBIAN_PACKAGE_RECOMMENDS "${_pg_recommends}")

# /usr/share/doc/planar-grid/copyright, where Debian's tools look for a package's licence:
# LICENSE in the machine-readable format (its copyright line and text, as they are).
# Only in the package: `cmake --install` keeps share/doc/PlanarGrid/LICENSE alone.
file(READ ${PROJECT_SOURCE_DIR}/LICENSE _pg_license)
string(REGEX MATCH "Copyright \\(c\\) ([^\n]+)\n(.*)$" _pg_match "${_pg_license}")
set(_pg_copyright "${CMAKE_MATCH_1}")
string(STRIP "${CMAKE_MATCH_2}" _pg_license_text)
# Continuation lines start with a space; an empty line is " .".
string(REPLACE "\n\n" "\n.\n" _pg_license_text "${_pg_license_text}")
string(REPLACE "\n" "\n " _pg_license_text " ${_pg_license_text}")
file(WRITE ${PROJECT_BINARY_DIR}/debian/copyright
  "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/\n"
  "Upstream-Name: ${PROJECT_NAME}\n\n"
  "Files: *\nCopyright: ${_pg_copyright}\nLicense: BSD-3-Clause\n${_pg_license_text}\n")
# CPack runs the script with DESTDIR at its staging folder, which file(INSTALL) prepends;
# CMAKE_INSTALL_PREFIX is not the package's prefix there.
# The same script installs lintian's overrides (cmake/planar-grid.lintian-overrides says
# which tags and why) where lintian looks for them.
file(WRITE ${PROJECT_BINARY_DIR}/debian/install_copyright.cmake
  "file(INSTALL ${PROJECT_BINARY_DIR}/debian/copyright\n"
  "     DESTINATION \"\${CPACK_PACKAGING_INSTALL_PREFIX}/share/doc/${CPACK_PACKAGE_NAME}\")\n"
  "file(INSTALL ${PROJECT_SOURCE_DIR}/cmake/planar-grid.lintian-overrides\n"
  "     DESTINATION \"\${CPACK_PACKAGING_INSTALL_PREFIX}/share/lintian/overrides\"\n"
  "     RENAME ${CPACK_PACKAGE_NAME})\n")
set(CPACK_INSTALL_SCRIPTS ${PROJECT_BINARY_DIR}/debian/install_copyright.cmake)

include(CPack)
