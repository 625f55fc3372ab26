# SPDX-License-Identifier: BSD-3-Clause
# The point types the template classes are explicitly instantiated for, set in one place:
# the cache list PLANAR_GRID_POINT_TYPES, validated against PCL's PCL_XYZ_POINT_TYPES and
# written as a Boost.PP sequence into the generated header <planar_grid/point_types.h>,
# which the precompiled sources expand with PLANAR_GRID_INSTANTIATE (PCL_INSTANTIATE's
# pattern). The header is installed, so that users of the installed package see the same list.

# Point types the library's own code (pipeline stages, tools) instantiates the classes for.
set(PLANAR_GRID_REQUIRED_POINT_TYPES pcl::PointXYZ pcl::PointXYZI)

# planar_grid_pcl_xyz_point_types(<out> <point_types.hpp>): the names in PCL's
# PCL_XYZ_POINT_TYPES (every PCL point type with x, y and z) as a list, e.g. pcl::PointXYZ.
function(planar_grid_pcl_xyz_point_types out header)
  if(NOT EXISTS "${header}")
    message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES: PCL's ${header} does not exist; it is "
      "needed to check the point type names")
  endif()
  file(READ "${header}" text)
  # The #define with its backslash-continued lines, up to the first line without one.
  if(NOT text MATCHES "#define PCL_XYZ_POINT_TYPES[ \t]*\\\\\n(([^\n]*\\\\\n)*[^\n]*)\n")
    message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES: no PCL_XYZ_POINT_TYPES in ${header}")
  endif()
  string(REGEX MATCHALL "\\(([A-Za-z_:0-9]+)\\)" items "${CMAKE_MATCH_1}")
  string(REGEX REPLACE "[()]" "" items "${items}")
  set(${out} "${items}" PARENT_SCOPE)
endfunction()

# planar_grid_normalize_point_types(<out> <value> <allowed> <required>): <value> as a list of
# fully qualified names. Accepts a CMake list (pcl::PointXYZ;pcl::PointXYZI), the names
# without "pcl::", or PCL's Boost.PP sequence form (pcl::PointXYZ)(pcl::PointXYZI).
# Unknown names, an empty list or a missing required type end the configuration with
# FATAL_ERROR; repeated names are kept once.
function(planar_grid_normalize_point_types out value allowed required)
  string(STRIP "${value}" value)
  if(value MATCHES "^\\(.*\\)$")
    string(REGEX REPLACE "\\)[ \t]*\\(" ";" value "${value}")
    string(REGEX REPLACE "^\\(|\\)$" "" value "${value}")
  endif()
  set(types "")
  set(unknown "")
  foreach(name IN LISTS value)
    string(STRIP "${name}" name)
    if(name STREQUAL "")
      continue()
    endif()
    set(qualified "${name}")
    if(NOT name MATCHES "::")
      set(qualified "pcl::${name}")
    endif()
    if(qualified IN_LIST allowed)
      list(APPEND types "${qualified}")
    else()
      list(APPEND unknown "${name}")
    endif()
  endforeach()
  string(REPLACE ";" " " allowed_text "${allowed}")
  if(unknown)
    string(REPLACE ";" ", " unknown_text "${unknown}")
    message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES: unknown point type(s) ${unknown_text}. "
      "Allowed are PCL's point types with x, y and z (PCL_XYZ_POINT_TYPES): ${allowed_text}")
  endif()
  if(NOT types)
    message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES is empty. List one or more of: "
      "${allowed_text}")
  endif()
  list(REMOVE_DUPLICATES types)
  foreach(name IN LISTS required)
    if(NOT name IN_LIST types)
      string(REPLACE ";" " " required_text "${required}")
      message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES must contain ${name}: the pipeline "
        "stages and tools use the classes with ${required_text}")
    endif()
  endforeach()
  set(${out} "${types}" PARENT_SCOPE)
endfunction()

# planar_grid_configure_point_types(): validates PLANAR_GRID_POINT_TYPES (call after
# find_package(PCL)), generates <binary dir>/include/planar_grid/point_types.h and installs it.
function(planar_grid_configure_point_types)
  find_file(PLANAR_GRID_PCL_POINT_TYPES_HPP pcl/impl/point_types.hpp
    HINTS ${PCL_INCLUDE_DIRS} NO_DEFAULT_PATH)
  if(NOT PLANAR_GRID_PCL_POINT_TYPES_HPP)
    message(FATAL_ERROR "PLANAR_GRID_POINT_TYPES: pcl/impl/point_types.hpp not found in "
      "PCL_INCLUDE_DIRS (${PCL_INCLUDE_DIRS})")
  endif()
  planar_grid_pcl_xyz_point_types(allowed "${PLANAR_GRID_PCL_POINT_TYPES_HPP}")
  planar_grid_normalize_point_types(types "${PLANAR_GRID_POINT_TYPES}" "${allowed}"
    "${PLANAR_GRID_REQUIRED_POINT_TYPES}")
  string(REPLACE ";" ", " types_text "${types}")
  message(STATUS "PlanarGrid point types: ${types_text}")
  # The checked list, fully qualified, for the tests.
  set(PLANAR_GRID_POINT_TYPES_LIST "${types}" PARENT_SCOPE)

  set(PLANAR_GRID_POINT_TYPES_SEQ "")
  foreach(name IN LISTS types)
    string(APPEND PLANAR_GRID_POINT_TYPES_SEQ " \\\n  (${name})")
  endforeach()
  set(header ${PROJECT_BINARY_DIR}/include/planar_grid/point_types.h)
  configure_file(${PROJECT_SOURCE_DIR}/cmake/point_types.h.in ${header} @ONLY)
  install(FILES ${header} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/planar_grid)
endfunction()

# planar_grid_use_point_types(<target>...): the targets see <planar_grid/point_types.h>
# (in the build tree; installed, it sits beside their own headers).
function(planar_grid_use_point_types)
  foreach(target IN LISTS ARGN)
    target_include_directories(${target} PUBLIC
      $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>)
  endforeach()
endfunction()
