# SPDX-License-Identifier: BSD-3-Clause
# cmake -P checks of PLANAR_GRID_POINT_TYPES (cmake/PlanarGridPointTypes.cmake).
#
#   -DMODE=normalize -DPCL_POINT_TYPES_HPP=<pcl/impl/point_types.hpp> -DPOINT_TYPES=<value>
#       prints "point types: <checked list>" or ends with the module's FATAL_ERROR.
#   -DMODE=libraries -DNM=<nm> -DPOINT_TYPES=<checked list> -DLIBRARIES=<library>,...
#       checks that the libraries define SACMultiPlaneSegmentation,
#       PlanarCuboidApproximation, KLDivergenceOccupancyFilter and
#       FastStatisticalOutlierRemoval for exactly the listed point types, and no others.
cmake_minimum_required(VERSION 3.16)

# Lists are passed comma-separated (a ';' would split the test's command line).
include(${CMAKE_CURRENT_LIST_DIR}/../../cmake/PlanarGridPointTypes.cmake)
string(REPLACE "," ";" POINT_TYPES "${POINT_TYPES}")

if(MODE STREQUAL "normalize")
  planar_grid_pcl_xyz_point_types(allowed "${PCL_POINT_TYPES_HPP}")
  planar_grid_normalize_point_types(types "${POINT_TYPES}" "${allowed}"
    "${PLANAR_GRID_REQUIRED_POINT_TYPES}")
  message("point types: ${types}")
elseif(MODE STREQUAL "libraries")
  string(REPLACE "," ";" libraries "${LIBRARIES}")
  set(expected ${POINT_TYPES})
  list(SORT expected)
  foreach(class SACMultiPlaneSegmentation PlanarCuboidApproximation
                KLDivergenceOccupancyFilter FastStatisticalOutlierRemoval)
    set(found "")
    foreach(library IN LISTS libraries)
      execute_process(COMMAND ${NM} -C --defined-only "${library}"
        OUTPUT_VARIABLE symbols RESULT_VARIABLE result)
      if(NOT result EQUAL 0)
        message(FATAL_ERROR "${NM} failed on ${library}")
      endif()
      string(REGEX MATCHALL "planar_grid::${class}<[A-Za-z0-9_:]+>::" hits "${symbols}")
      foreach(hit IN LISTS hits)
        string(REGEX REPLACE "^planar_grid::${class}<(.*)>::$" "\\1" type "${hit}")
        list(APPEND found "${type}")
      endforeach()
    endforeach()
    if(found)
      list(REMOVE_DUPLICATES found)
      list(SORT found)
    endif()
    if(NOT found STREQUAL expected)
      message(FATAL_ERROR "planar_grid::${class} is instantiated for [${found}], "
        "PLANAR_GRID_POINT_TYPES lists [${expected}]")
    endif()
    message("planar_grid::${class}: ${found}")
  endforeach()
else()
  message(FATAL_ERROR "MODE must be normalize or libraries, got '${MODE}'")
endif()
