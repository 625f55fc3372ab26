# SPDX-License-Identifier: BSD-3-Clause
# Manual pages of the installed programs, section 1 (`man planar_grid_pipeline`), made at
# build time by help2man (Debian's help2man) from each program's own --help and --version,
# so that they say what the program says; installed to share/man/man1. Without help2man,
# or in a sanitizer build (whose programs are not installed), there are none.
#
#   planar_grid_install_man_pages(<target> "<one-line description>" ...)
#   planar_grid_install_man_page_script(<name> "<one-line description>" <dir> <depends>...)
#
# The first takes executable targets (the page is named after OUTPUT_NAME); the second a
# program file <dir>/<name> that is not a target, e.g. the build tree's Python entry
# point, rebuilt when <depends> (files or targets) change.

find_program(PLANAR_GRID_HELP2MAN help2man DOC "help2man, for the programs' manual pages")
find_program(PLANAR_GRID_GZIP gzip DOC "gzip, for the manual pages")
if(PLANAR_GRID_HELP2MAN AND PLANAR_GRID_GZIP AND NOT PLANAR_GRID_SANITIZE)
  set(PLANAR_GRID_MAN_PAGES ON)
  add_custom_target(planar_grid_man_pages ALL)
else()
  set(PLANAR_GRID_MAN_PAGES OFF)
  if(NOT PLANAR_GRID_SANITIZE)
    message(STATUS "help2man not found: no manual pages (apt-get install help2man)")
  endif()
endif()

# One page for the program NAME in the folder DIR (a path or a generator expression),
# rebuilt when DEPENDS change. help2man runs it by its bare name, found on PATH, so that
# the page shows "planar_grid_pipeline", not the build folder's path.
function(_planar_grid_man_page name description dir depends)
  set(page ${PROJECT_BINARY_DIR}/man/${name}.1)
  # NO_COLOR: the help text without terminal colour codes. Compressed as man-db reads
  # them and Debian installs them (gzip -n: no name or time stamp in the file).
  add_custom_command(OUTPUT ${page}.gz
    COMMAND ${CMAKE_COMMAND} -E make_directory ${PROJECT_BINARY_DIR}/man
    COMMAND ${CMAKE_COMMAND} -E env NO_COLOR=1 "PATH=${dir}:/usr/bin:/bin"
            ${PLANAR_GRID_HELP2MAN} --no-info --no-discard-stderr --section=1
            --name=${description} --output=${page} ${name}
    COMMAND ${PLANAR_GRID_GZIP} -9nf ${page}
    DEPENDS ${depends}
    COMMENT "Manual page ${name}.1"
    VERBATIM)
  add_custom_target(planar_grid_man_${name} DEPENDS ${page}.gz)
  add_dependencies(planar_grid_man_pages planar_grid_man_${name})
  install(FILES ${page}.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
endfunction()

function(planar_grid_install_man_pages)
  if(NOT PLANAR_GRID_MAN_PAGES)
    return()
  endif()
  set(args ${ARGN})
  list(LENGTH args count)
  math(EXPR last "${count} - 1")
  foreach(i RANGE 0 ${last} 2)
    math(EXPR j "${i} + 1")
    list(GET args ${i} target)
    list(GET args ${j} description)
    if(TARGET ${target})
      get_target_property(name ${target} OUTPUT_NAME)
      if(NOT name)
        set(name ${target})
      endif()
      _planar_grid_man_page(${name} "${description}" $<TARGET_FILE_DIR:${target}> ${target})
    endif()
  endforeach()
endfunction()

function(planar_grid_install_man_page_script name description dir)
  if(NOT PLANAR_GRID_MAN_PAGES)
    return()
  endif()
  _planar_grid_man_page(${name} "${description}" ${dir} "${dir}/${name};${ARGN}")
endfunction()
