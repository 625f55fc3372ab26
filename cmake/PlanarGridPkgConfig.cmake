# SPDX-License-Identifier: BSD-3-Clause
# planar_grid_install_pkgconfig(): <prefix>/<pkgconfig dir>/planar_grid.pc (every
# module that was built) and planar_grid_<module>.pc (one module and the modules it
# uses, with only their dependencies: a segmentation-only program needs neither VTK nor
# OpenCV), for projects that build with pkg-config instead of CMake. Call it once,
# after every module was added.
#
# The folder, PLANAR_GRID_PKGCONFIG_INSTALL_DIR (relative to the prefix), is by default
# <libdir>/<multiarch triplet>/pkgconfig where the compiler has one (Debian:
# lib/x86_64-linux-gnu/pkgconfig, which pkg-config searches under /usr and /usr/local
# and Debian's policy asks of .pc files that name architecture-specific paths), else
# <libdir>/pkgconfig.
#
# What pkg-config can express of the two kinds of build:
# - shared libraries (BUILD_SHARED_LIBS): Libs lists our libraries, Requires the
#   packages whose headers our public headers include (PCL, Eigen, OpenCV, ...), and
#   Requires.private / Libs.private the packages our libraries link privately; those
#   are found through the libraries' own dependencies at run time, and
#   `pkg-config --static` adds them for a static link of everything.
# - static libraries: every dependency is needed on the link line of the program, so
#   every package goes to Requires and Libs, and plain `pkg-config --libs` is enough.
# Packages without a .pc file in Debian (VTK) are given as the full paths of their
# libraries. Our libraries are listed so that each comes before the ones it uses.

# Maps a link item to a pkg-config module (_pg_pc) or a linker flag or file (_pg_flag).
macro(_planar_grid_pc_item item)
  set(_pg_pc "")
  set(_pg_flag "")
  if("${item}" MATCHES "^planar_grid_")
    # our own libraries: in Libs
  elseif("${item}" MATCHES "^pcl_")
    set(_pg_pc "${item}")
  elseif("${item}" MATCHES "^opencv_")
    set(_pg_pc opencv4)
  elseif("${item}" STREQUAL "Eigen3::Eigen")
    set(_pg_pc eigen3)
  elseif("${item}" STREQUAL "yaml-cpp")
    set(_pg_pc yaml-cpp)
  elseif("${item}" MATCHES "^nlohmann_json::")
    set(_pg_pc nlohmann_json)
  elseif("${item}" STREQUAL "octomap" OR "${item}" STREQUAL "octomath")
    set(_pg_pc octomap)
  elseif("${item}" STREQUAL "nanoflann::nanoflann")
    set(_pg_pc nanoflann)
  elseif("${item}" MATCHES "^X11::")
    set(_pg_pc x11)
  elseif("${item}" STREQUAL "Threads::Threads")
    set(_pg_flag "-pthread")
  elseif("${item}" MATCHES "^OpenMP::")
    set(_pg_flag "-fopenmp")
  elseif("${item}" MATCHES "^VTK::" AND TARGET "${item}")
    set(_pg_flag "$<TARGET_LINKER_FILE:${item}>")
  elseif(IS_ABSOLUTE "${item}" AND "${item}" MATCHES "/lib([^/]+)\\.(so|a)$")
    # A library found by its file (the ROS 1 libraries, whose Debian .pc files require
    # packages that have none): -l<name>, with -L<dir> outside the linker's own paths.
    get_filename_component(_pg_dir "${item}" DIRECTORY)
    if(_pg_dir IN_LIST CMAKE_CXX_IMPLICIT_LINK_DIRECTORIES)
      set(_pg_flag "-l${CMAKE_MATCH_1}")
    else()
      set(_pg_flag "-L${_pg_dir};-l${CMAKE_MATCH_1}")
    endif()
  elseif(NOT "${item}" STREQUAL "")
    message(AUTHOR_WARNING "planar_grid_install_pkgconfig: no pkg-config module known "
      "for the link item '${item}'; add it to cmake/PlanarGridPkgConfig.cmake")
  endif()
endmacro()

# Depth-first visit of the modules' dependencies: appends \a module to the variable
# _pg_order after every module it links.
function(_planar_grid_pc_visit module)
  if(module IN_LIST _pg_order)
    set(_pg_order "${_pg_order}" PARENT_SCOPE)
    return()
  endif()
  get_property(links GLOBAL PROPERTY PLANAR_GRID_${module}_LINKS)
  foreach(item IN LISTS links)
    if("${item}" MATCHES "^planar_grid_(.+)$" AND TARGET "${item}")
      _planar_grid_pc_visit(${CMAKE_MATCH_1})
    endif()
  endforeach()
  list(APPEND _pg_order ${module})
  set(_pg_order "${_pg_order}" PARENT_SCOPE)
endfunction()

if(CMAKE_LIBRARY_ARCHITECTURE AND NOT CMAKE_INSTALL_LIBDIR MATCHES "${CMAKE_LIBRARY_ARCHITECTURE}")
  set(_pg_pkgconfig_dir "${CMAKE_INSTALL_LIBDIR}/${CMAKE_LIBRARY_ARCHITECTURE}/pkgconfig")
else()
  set(_pg_pkgconfig_dir "${CMAKE_INSTALL_LIBDIR}/pkgconfig")
endif()
set(PLANAR_GRID_PKGCONFIG_INSTALL_DIR "${_pg_pkgconfig_dir}"
    CACHE STRING "Install folder of the .pc files, relative to the prefix")

function(planar_grid_install_pkgconfig)
  get_property(modules GLOBAL PROPERTY PLANAR_GRID_MODULES)
  _planar_grid_write_pc(planar_grid "every module" ${modules})
  foreach(module IN LISTS modules)
    _planar_grid_write_pc(planar_grid_${module} "the ${module} module" ${module})
  endforeach()
endfunction()

# Writes and installs <pc_name>.pc for \a ARGN modules and every module they use.
function(_planar_grid_write_pc pc_name what)
  set(_pg_order "")
  foreach(module IN LISTS ARGN)
    _planar_grid_pc_visit(${module})
  endforeach()
  # Dependents first on the link line.
  list(REVERSE _pg_order)
  set(libs "")
  foreach(module IN LISTS _pg_order)
    string(APPEND libs " -lplanar_grid_${module}")
  endforeach()
  string(STRIP "${libs}" libs)

  set(requires "")
  set(requires_private "")
  set(flags "")
  set(flags_private "")
  foreach(module IN LISTS _pg_order)
    get_property(public GLOBAL PROPERTY PLANAR_GRID_${module}_PUBLIC_LINKS)
    get_property(all GLOBAL PROPERTY PLANAR_GRID_${module}_LINKS)
    # What a module's CMakeLists links besides planar_grid_add_library()'s DEPENDS and
    # PRIVATE_DEPENDS (an optional input's libraries) is linked privately.
    get_target_property(linked planar_grid_${module} LINK_LIBRARIES)
    if(linked)
      foreach(item IN LISTS linked)
        if(NOT item IN_LIST all)
          list(APPEND all "${item}")
        endif()
      endforeach()
    endif()
    foreach(item IN LISTS all)
      _planar_grid_pc_item("${item}")
      if(BUILD_SHARED_LIBS AND NOT item IN_LIST public)
        list(APPEND requires_private ${_pg_pc})
        list(APPEND flags_private ${_pg_flag})
      else()
        list(APPEND requires ${_pg_pc})
        list(APPEND flags ${_pg_flag})
      endif()
    endforeach()
  endforeach()
  foreach(list_name requires requires_private flags flags_private)
    if(${list_name})
      list(REMOVE_DUPLICATES ${list_name})
    endif()
  endforeach()
  if(requires)
    list(REMOVE_ITEM requires_private ${requires})
  endif()
  string(REPLACE ";" " " PLANAR_GRID_PC_REQUIRES "${requires}")
  string(REPLACE ";" " " PLANAR_GRID_PC_REQUIRES_PRIVATE "${requires_private}")
  string(REPLACE ";" " " flags "${flags}")
  string(REPLACE ";" " " PLANAR_GRID_PC_LIBS_PRIVATE "${flags_private}")
  set(PLANAR_GRID_PC_LIBS "${libs} ${flags}")
  string(STRIP "${PLANAR_GRID_PC_LIBS}" PLANAR_GRID_PC_LIBS)
  if(BUILD_SHARED_LIBS)
    set(PLANAR_GRID_PC_NOTE "Shared libraries: `pkg-config --static` adds what they link privately.")
  else()
    set(PLANAR_GRID_PC_NOTE "Static libraries: Requires and Libs hold every dependency.")
  endif()

  # Installed: the prefix is where the .pc file lies (pkg-config's pcfiledir), so that a
  # relocated install (DESTDIR, a copied prefix) still points at its own files.
  if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}" OR IS_ABSOLUTE "${CMAKE_INSTALL_INCLUDEDIR}")
    message(FATAL_ERROR "planar_grid.pc needs CMAKE_INSTALL_LIBDIR and "
      "CMAKE_INSTALL_INCLUDEDIR relative to the prefix")
  endif()
  file(RELATIVE_PATH to_prefix "/${PLANAR_GRID_PKGCONFIG_INSTALL_DIR}" "/")
  string(REGEX REPLACE "/$" "" to_prefix "${to_prefix}")
  set(PLANAR_GRID_PC_PREFIX "\${pcfiledir}/${to_prefix}")
  set(PLANAR_GRID_PC_NAME ${pc_name})
  set(PLANAR_GRID_PC_WHAT "${what}")
  configure_file(${PROJECT_SOURCE_DIR}/cmake/planar_grid.pc.in
                 ${PROJECT_BINARY_DIR}/pkgconfig/${pc_name}.pc.in @ONLY)
  # Generator expressions (VTK's library files) are resolved at generation time.
  file(GENERATE OUTPUT ${PROJECT_BINARY_DIR}/pkgconfig/${pc_name}.pc
       INPUT ${PROJECT_BINARY_DIR}/pkgconfig/${pc_name}.pc.in)
  install(FILES ${PROJECT_BINARY_DIR}/pkgconfig/${pc_name}.pc
          DESTINATION ${PLANAR_GRID_PKGCONFIG_INSTALL_DIR})
endfunction()
