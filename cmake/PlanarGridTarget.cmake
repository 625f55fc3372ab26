# SPDX-License-Identifier: BSD-3-Clause
# Helpers shared by every target: warnings and sanitizers set per target, nothing in
# global flags or include directories (a consumer of the package inherits none of them);
# install and export of every module in one place, so that each installs the same way.

include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

function(planar_grid_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  # PCL's exported targets put VTK, Qt and the rest of its dependencies on every link
  # line; linked as needed, a program loads only the shared libraries it calls (the
  # pipeline tool 255 instead of 278), which shortens every start of a tool, a test
  # executable and the Python module.
  if(NOT APPLE)
    target_link_options(${target} PRIVATE "LINKER:--as-needed")
  endif()
  if(PLANAR_GRID_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
    # Eigen turns its "malloc is already aligned" path off under __SANITIZE_ADDRESS__
    # and frees with its hand-made aligned free, while Debian's PCL (built without
    # ASan) allocated with plain malloc: a false heap-buffer-overflow whenever a cloud
    # filled inside libpcl_* is freed in our code. glibc's and ASan's malloc both align
    # to 16 bytes, so keep Eigen on the plain path like the system libraries.
    target_compile_definitions(${target} PRIVATE EIGEN_MALLOC_ALREADY_ALIGNED=1)
  endif()
endfunction()

# Precompiled headers: most sources include Eigen, PCL's point types and a good part of
# the standard library, and parsing them is most of a translation unit's compile time
# (about 150,000 lines before a line of ours). They are compiled once per kind of target
# and build: every library shares one precompiled header, every test executable another
# (with GoogleTest), each owned by an object library with exactly their flags, so the
# sanitizer and Release builds each get valid ones. Private to our targets: nothing of it
# is installed or seen by a consumer of the package.
option(PLANAR_GRID_PRECOMPILE_HEADERS
       "Precompile the common headers of the libraries, the tests and the Python module"
       ON)
set(PLANAR_GRID_PRECOMPILED_HEADERS
    <algorithm> <array> <cmath> <cstdint> <functional> <limits> <map> <memory> <sstream>
    <string> <unordered_map> <utility> <vector>
    <Eigen/Core> <Eigen/Geometry> <pcl/point_cloud.h> <pcl/point_types.h>)

# planar_grid_precompile_headers(<target> [<header>...]): the common headers, after the
# given ones (a header that must come first, like pybind11's Python.h, is listed here),
# precompiled for <target> alone when it has more than one source.
function(planar_grid_precompile_headers target)
  if(NOT PLANAR_GRID_PRECOMPILE_HEADERS)
    return()
  endif()
  get_target_property(sources ${target} SOURCES)
  list(LENGTH sources count)
  if(count LESS 2)
    return()
  endif()
  target_precompile_headers(${target} PRIVATE ${ARGN} ${PLANAR_GRID_PRECOMPILED_HEADERS})
endfunction()

# The code model of a target that shares a precompiled header. Objects of both libraries and
# executables are compiled -fPIC: Qt's targets (through VTK) add -fPIC to some of them, the
# compilers reject a header precompiled with another code model (clang with an error, GCC
# by ignoring it), and position-independent objects link into either. GCC says when it
# cannot use a precompiled header, which the warning-free build check turns into a failure.
function(_planar_grid_pch_flags target)
  target_compile_options(${target} PRIVATE -fPIC)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Winvalid-pch)
  endif()
endfunction()

# planar_grid_share_precompiled_headers(<target> <owner> LINKS <item>... [OPTIONS <opt>...]
#                                       [HEADERS <header>...]):
# <target> reuses the precompiled header of the object library <owner>, created on first
# use with the given links (for their include directories and definitions), compile
# options and headers (before the common ones). Every target sharing an owner must be
# compiled with the same flags as it: the owner gets the warnings, sanitizer flags and
# position independence that planar_grid_set_warnings() and the target type give them.
function(planar_grid_share_precompiled_headers target owner)
  if(NOT PLANAR_GRID_PRECOMPILE_HEADERS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "LINKS;OPTIONS;HEADERS" ${ARGN})
  if(NOT TARGET ${owner})
    set(source "${PROJECT_BINARY_DIR}/${owner}.cpp")
    file(CONFIGURE OUTPUT "${source}"
         CONTENT "// The owner of a shared precompiled header: no code of its own.\n")
    add_library(${owner} OBJECT "${source}")
    target_link_libraries(${owner} PRIVATE ${ARG_LINKS})
    target_compile_options(${owner} PRIVATE ${ARG_OPTIONS})
    planar_grid_set_warnings(${owner})
    _planar_grid_pch_flags(${owner})
    target_precompile_headers(${owner} PRIVATE ${ARG_HEADERS} ${PLANAR_GRID_PRECOMPILED_HEADERS})
  endif()
  _planar_grid_pch_flags(${target})
  target_precompile_headers(${target} REUSE_FROM ${owner})
endfunction()

# planar_grid_add_library(<module> SOURCES ... DEPENDS ... PRIVATE_DEPENDS ...): the library
# planar_grid_<module> with include/ as its public include directory. It is installed with
# its headers (including impl/*.hpp, for PCL_NO_PRECOMPILE users) and exported as
# PlanarGrid::<module>, the COMPONENT <module> of find_package(PlanarGrid). DEPENDS and
# PRIVATE_DEPENDS are recorded so that the package config finds exactly the packages
# the requested components need (planar_grid_install_package()).
function(planar_grid_add_library module)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS;PRIVATE_DEPENDS" ${ARGN})
  set(target planar_grid_${module})
  add_library(${target} ${ARG_SOURCES})
  add_library(PlanarGrid::${module} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${module})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:include>)
  # Users of the installed package get C++17 from the target, not from their own flags.
  target_compile_features(${target} PUBLIC cxx_std_17)
  target_link_libraries(${target} PUBLIC ${ARG_DEPENDS} PRIVATE ${ARG_PRIVATE_DEPENDS})
  planar_grid_set_warnings(${target})
  planar_grid_share_precompiled_headers(${target} planar_grid_library_pch
    LINKS Eigen3::Eigen pcl_common)

  install(TARGETS ${target} EXPORT PlanarGridTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
    RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/include/planar_grid)
    install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/include/planar_grid
      DESTINATION include
      FILES_MATCHING PATTERN "*.h" PATTERN "*.hpp")
  endif()
  set_property(GLOBAL APPEND PROPERTY PLANAR_GRID_MODULES ${module})
  set_property(GLOBAL PROPERTY PLANAR_GRID_${module}_LINKS ${ARG_DEPENDS} ${ARG_PRIVATE_DEPENDS})
  set_property(GLOBAL PROPERTY PLANAR_GRID_${module}_PUBLIC_LINKS ${ARG_DEPENDS})
endfunction()

# planar_grid_install_tools(<target>...): installs the existing executables to bin/.
function(planar_grid_install_tools)
  foreach(tool IN LISTS ARGN)
    if(TARGET ${tool})
      install(TARGETS ${tool} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
    endif()
  endforeach()
endfunction()

# Maps one link item of a module to what the package config must find for it. Sets, in the
# caller: _pg_kind (module | pcl | opencv | vtk | package | skip) and _pg_name.
macro(_planar_grid_classify_link item)
  set(_pg_kind skip)
  set(_pg_name "")
  if("${item}" MATCHES "^planar_grid_(.+)$")
    set(_pg_kind module)
    set(_pg_name ${CMAKE_MATCH_1})
  elseif("${item}" MATCHES "^pcl_(.+)$")
    set(_pg_kind pcl)
    set(_pg_name ${CMAKE_MATCH_1})
  elseif("${item}" MATCHES "^opencv_(.+)$")
    set(_pg_kind opencv)
    set(_pg_name ${CMAKE_MATCH_1})
  elseif("${item}" MATCHES "^VTK::(.+)$")
    set(_pg_kind vtk)
    set(_pg_name ${CMAKE_MATCH_1})
  elseif("${item}" STREQUAL "Eigen3::Eigen")
    set(_pg_kind package)
    set(_pg_name "Eigen3 3.3 NO_MODULE")
  elseif("${item}" STREQUAL "yaml-cpp")
    set(_pg_kind package)
    set(_pg_name "yaml-cpp")
  elseif("${item}" MATCHES "^nlohmann_json::")
    set(_pg_kind package)
    set(_pg_name "nlohmann_json 3")
  elseif("${item}" STREQUAL "octomap" OR "${item}" STREQUAL "octomath")
    set(_pg_kind package)
    set(_pg_name "octomap")
  elseif("${item}" STREQUAL "nanoflann::nanoflann")
    set(_pg_kind package)
    set(_pg_name "nanoflann")
  elseif("${item}" MATCHES "^X11::")
    set(_pg_kind package)
    set(_pg_name "X11")
  elseif("${item}" STREQUAL "Threads::Threads")
    set(_pg_kind package)
    set(_pg_name "Threads")
  elseif("${item}" MATCHES "^OpenMP::")
    set(_pg_kind package)
    set(_pg_name "OpenMP")
  else()
    message(AUTHOR_WARNING "planar_grid_install_package: no find_dependency known for the "
      "link item '${item}'; add it to _planar_grid_classify_link in cmake/PlanarGridTarget.cmake")
  endif()
endmacro()

# planar_grid_install_package(): PlanarGridTargets.cmake (namespace PlanarGrid::),
# PlanarGridConfig.cmake with one COMPONENT per module and the dependencies each needs,
# and PlanarGridConfigVersion.cmake, in <prefix>/lib/cmake/PlanarGrid. Call it once, after
# every module was added.
function(planar_grid_install_package)
  get_property(modules GLOBAL PROPERTY PLANAR_GRID_MODULES)
  set(table "")
  foreach(module IN LISTS modules)
    get_property(links GLOBAL PROPERTY PLANAR_GRID_${module}_LINKS)
    set(deps "")
    set(pcl "")
    set(opencv "")
    set(vtk "")
    set(packages "")
    foreach(item IN LISTS links)
      _planar_grid_classify_link("${item}")
      if(_pg_kind STREQUAL "module")
        list(APPEND deps ${_pg_name})
      elseif(_pg_kind STREQUAL "pcl")
        list(APPEND pcl ${_pg_name})
      elseif(_pg_kind STREQUAL "opencv")
        list(APPEND opencv ${_pg_name})
      elseif(_pg_kind STREQUAL "vtk")
        list(APPEND vtk ${_pg_name})
      elseif(_pg_kind STREQUAL "package")
        list(APPEND packages "${_pg_name}")
      endif()
    endforeach()
    foreach(list_name deps pcl opencv vtk packages)
      if(${list_name})
        list(REMOVE_DUPLICATES ${list_name})
      endif()
    endforeach()
    # Packages are stored with '|' in place of ';' so that "Eigen3 3.3 NO_MODULE" stays one item.
    string(REPLACE " " "|" packages "${packages}")
    string(APPEND table
      "set(_PlanarGrid_${module}_modules \"${deps}\")\n"
      "set(_PlanarGrid_${module}_pcl \"${pcl}\")\n"
      "set(_PlanarGrid_${module}_opencv \"${opencv}\")\n"
      "set(_PlanarGrid_${module}_vtk \"${vtk}\")\n"
      "set(_PlanarGrid_${module}_packages \"${packages}\")\n")
  endforeach()
  set(PLANAR_GRID_MODULE_LIST "${modules}")
  set(PLANAR_GRID_COMPONENT_TABLE "${table}")

  set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/PlanarGrid)
  configure_package_config_file(
    ${PROJECT_SOURCE_DIR}/cmake/PlanarGridConfig.cmake.in
    ${PROJECT_BINARY_DIR}/PlanarGridConfig.cmake
    INSTALL_DESTINATION ${config_dir})
  write_basic_package_version_file(
    ${PROJECT_BINARY_DIR}/PlanarGridConfigVersion.cmake
    VERSION ${PROJECT_VERSION}
    COMPATIBILITY SameMinorVersion)
  install(EXPORT PlanarGridTargets
    NAMESPACE PlanarGrid::
    DESTINATION ${config_dir})
  install(FILES
    ${PROJECT_BINARY_DIR}/PlanarGridConfig.cmake
    ${PROJECT_BINARY_DIR}/PlanarGridConfigVersion.cmake
    DESTINATION ${config_dir})
endfunction()
